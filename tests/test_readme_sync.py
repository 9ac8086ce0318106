import pytest

from host_tools.readme_sync import BEGIN, END, main, splice


def test_splice_replaces_only_between_the_markers():
    readme = f"# title\nintro\n{BEGIN}\nold table\n{END}\nafter\n"
    out = splice(readme, "| new |")
    assert out == f"# title\nintro\n{BEGIN}\n\n| new |\n\n{END}\nafter\n"
    assert splice(out, "| new |") == out          # idempotent


@pytest.mark.parametrize("readme", ["no markers\n", f"{END}\n{BEGIN}\n", f"{BEGIN}\n{BEGIN}\n{END}\n"])
def test_missing_or_misordered_markers_are_an_error(readme):
    with pytest.raises(ValueError, match="expected one line"):
        splice(readme, "x")


def test_main_leaves_the_readme_alone_on_error(tmp_path, capsys):
    readme = tmp_path / "README.md"
    readme.write_text("no markers\n")
    gen = tmp_path / "t.md"
    gen.write_text("| t |\n")
    assert main([str(gen), str(readme)]) == 2
    assert readme.read_text() == "no markers\n"
    assert "README.md: expected one line" in capsys.readouterr().err
