"""Readers of dataset formats: files -> validated plain records; no database."""
