"""The progress callback of long work (imports, recomputes, exports): ``progress(stage, done, total)``."""
from __future__ import annotations

from typing import Callable

#: ``progress(stage, done, total)``: called as work advances (the CLI draws a tqdm bar from it, a job stores it).
Progress = Callable[[str, int, int], None]
