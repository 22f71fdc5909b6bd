"""Tests of app.services.curation."""
