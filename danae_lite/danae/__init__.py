"""The DANAE networks, their windows, training (seeds, checkpoints, the network cache) and prediction."""
