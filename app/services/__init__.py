"""The services: what v3d does with its data (import, calibration, curation, review, export, jobs), below the API
and the CLI. The ISSIA services register their kind's hooks here, before any service runs (``app.services.issia``).
"""
import app.services.issia  # noqa: F401  # registers the ISSIA kind's hooks
