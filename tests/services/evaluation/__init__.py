"""Tests of app.services.evaluation."""
