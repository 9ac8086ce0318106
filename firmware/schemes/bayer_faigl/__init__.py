from firmware.schemes.bayer_faigl.scheme import BayerFaigl

__all__ = ["BayerFaigl"]
