"""The AOASS safety stack: Kalman tracking, fuzzy control, ORCA."""
