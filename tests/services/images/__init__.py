"""Tests of app.services.images."""
