"""``v3d doubts``: the stored doubts of every system in the database (``app.services.derivation.doubts``).

Without ``--json`` it prints a table: per doubt kind, how many doubts and how many systems carry one.
With ``--json OUT`` it also writes ``{"systems": [{"game": {"league", "season", "match"}, "system":
<action image name>, "doubts": [{"kind", "frame": <image name> | null, "message", "evidence",
"suggestion", ...}]}]}``. Doubts are stored by every import and edit; only systems stored by an
older version of v3d (before doubts existed) are recomputed first.
"""
from __future__ import annotations

import json
from collections import Counter
from pathlib import Path
from typing import Annotated, Optional

import typer

from app.cli._root import cli
from app.cli.datasets import DatabaseOpt, cli_settings, database_session
from app.geometry.doubts import INFO_KINDS, LABEL_KINDS


@cli.command("doubts")
def doubts_cmd(
    json_out: Annotated[Optional[Path],
                        typer.Option("--json", help="Write every system's doubts to this JSON file.")] = None,
    database_url: DatabaseOpt = None,
) -> None:
    """Report the doubts of every system: counts per kind, and optionally the whole list as JSON."""
    from app.services.derivation.doubts import doubts_report
    from app.services.derivation.recompute import refresh_stale_systems

    settings = cli_settings(database_url, None)
    with database_session(settings) as session:
        refresh_stale_systems(session, settings)  # a database stored before doubts existed
        report = doubts_report(session)
    doubts_n: Counter = Counter()
    systems_n: Counter = Counter()
    for s in report["systems"]:
        kinds = [d["kind"] for d in s["doubts"]]
        doubts_n.update(kinds)
        systems_n.update(set(kinds))
    accused = sum(1 for s in report["systems"] if any(d["accuses_label"] for d in s["doubts"]))
    typer.echo(f"{len(report['systems'])} system(s), {accused} with a label-accusing doubt")
    typer.echo(f"{'kind':<22} {'doubts':>7} {'systems':>8}")
    for kind in (*LABEL_KINDS, *INFO_KINDS, *sorted(set(doubts_n) - set(LABEL_KINDS) - set(INFO_KINDS))):
        tag = "" if kind in LABEL_KINDS else "  (information)"
        typer.echo(f"{kind:<22} {doubts_n[kind]:>7} {systems_n[kind]:>8}{tag}")
    if json_out is not None:
        json_out.parent.mkdir(parents=True, exist_ok=True)
        json_out.write_text(json.dumps(report, indent=1))
        typer.echo(f"wrote {json_out}")
