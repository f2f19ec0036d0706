"""Robot descriptions and calibration files."""
