"""Per-annotator figures and every audit entry since an ISO date or time (UTC when it names no offset), as JSON.

    python examples/client/08_activity.py 2026-11-01

A reviewer's token at least (the figures are the reviewers'; changes of users and tokens are listed to admins).
"""
from __future__ import annotations

import json
import sys
from datetime import datetime, timezone

from v3d_client import Client


def main(since_text: str) -> None:
    since = datetime.fromisoformat(since_text)
    if since.tzinfo is None:
        since = since.replace(tzinfo=timezone.utc)
    with Client.from_env() as v3d:
        figures = [a.model_dump(mode="json") for a in v3d.annotators(since=since)]
        entries = [e.model_dump(mode="json") for e in v3d.audit(since=since)]
    print(json.dumps({"since": since.isoformat(), "annotators": figures, "audit": entries}, indent=2))


if __name__ == "__main__":
    main(sys.argv[1])
