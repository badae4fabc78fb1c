"""The paper's experiment: its DANAE, Tables 1-2 and Figures 1-2."""
