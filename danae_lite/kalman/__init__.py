"""The paper's linear attitude Kalman filter: its model, the filter, its gains, the grid over settings, the smoother."""
