"""Tests of app.services.calibration."""
