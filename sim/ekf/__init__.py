"""The EKF core's models: the bit-exact golden runner and a float64 reference."""
