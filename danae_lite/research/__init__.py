"""The research engine: what chapters 5 onward add on top of the core (baselines and library
filters, the leaderboard, cross-validation, the learned denoisers). It imports the core, never
the entry points; the modules are listed in :mod:`danae_lite`."""
