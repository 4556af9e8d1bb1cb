"""The extended Kalman filter core on the linear-algebra engine: the application's f and h (the
UKF's application class) compiled with their Jacobians by forward-mode differentiation, and
the EKF's iteration as one program."""
