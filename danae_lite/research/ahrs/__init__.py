"""Established attitude filters: the libraries' Fusion, VQF, Madgwick, Mahony, RIANN, and Madgwick/Mahony over a grid of gains."""
