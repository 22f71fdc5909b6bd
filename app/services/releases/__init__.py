"""Releases: named, immutable, reproducible snapshots of the accepted systems (:mod:`.content`), what changed
between two (:mod:`.diff`), and the exports read from one (``app.services.transfer.exporting``)."""
