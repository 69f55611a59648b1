"""Four-point-contact linear ball bearing (paper Sec. 2): numerical and analytical models."""
