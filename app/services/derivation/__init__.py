"""The derivation engine: what is computed from the stored labels (calibration, triangulation, optimised boxes,
doubts, the queue's figures), for an edit, an import, an ISSIA sequence or a job alike."""
