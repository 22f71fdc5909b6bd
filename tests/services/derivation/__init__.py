"""Tests of app.services.derivation."""
