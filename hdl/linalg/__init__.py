"""The linear-algebra engine shared by the UKF and IMM cores: step programs, their list
scheduler and compact program store (pure Python, fixed at generation)."""
