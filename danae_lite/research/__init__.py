"""Research: past the paper (baselines and library filters, the leaderboard, cross-validation,
the learned denoisers DANAE-res and DANAE-safe). It imports the rooms above it in the package
map, never the entry points; the modules are listed in :mod:`danae_lite`."""
