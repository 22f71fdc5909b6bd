"""Tests of app.services.issia."""
