"""The core: what chapters 1-4 need (the paper's KF, the datasets, DANAE and its training, the
paper's tables and figures). It imports nothing from the research engine or the entry points;
the modules are listed in :mod:`danae_lite`."""
