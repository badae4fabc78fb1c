"""Recordings: the one Recording type, the datasets' loaders, the simulator, ground truth, the paper's experiments, alignment."""
