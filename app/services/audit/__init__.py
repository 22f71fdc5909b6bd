"""The audit log: every accepted write as one entry (log), its words (summaries), and its revert or undo
(reverting)."""
