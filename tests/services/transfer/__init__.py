"""Tests of app.services.transfer."""
