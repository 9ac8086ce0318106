"""Wireshark dissector for lorascout frames, generated from the record table."""
