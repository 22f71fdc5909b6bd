"""Backups of a whole deployment and their restore, from any engine and store to any other: the archive's format and
its verification (``archive``), the neutral rows (``rows``), the snapshot (``snapshot``: ``v3d backup``, the backup
job) and the restore (``restore``: ``v3d restore``)."""
