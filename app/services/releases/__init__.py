"""Releases: named, immutable, reproducible snapshots of the accepted systems (:mod:`.content`), their documents'
typed shape per version (:mod:`.document`), what changed between two (:mod:`.diff`), and the exports read from one
(:mod:`.export`, through the typed rows of :mod:`.rows`)."""
