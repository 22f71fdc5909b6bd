"""Tests of app.services.wording."""
