"""The paper's error metrics and the one scoring rule of every table."""
