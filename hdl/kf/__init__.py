"""The linear Kalman filter core (the user's F, B, H, Q, R in the buffer) on the linear-algebra
engine."""
