"""Calibration: discrepancy verdicts, trials and compensation."""
