"""Ball screw friction with ball-to-ball contact (paper Sec. 3)."""
