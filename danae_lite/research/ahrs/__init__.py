"""Established attitude filters: the libraries' Fusion, VQF, Madgwick, Mahony and RIANN
(:mod:`~danae_lite.research.ahrs.filters`), Madgwick and Mahony over a grid of gains in one pass
(:mod:`~danae_lite.research.ahrs.grid`) and as the BROAD benchmark ran them
(:mod:`~danae_lite.research.ahrs.broad_reference`)."""
