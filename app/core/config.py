"""Settings of the service, read from the environment (prefix ``V3D_``) and ``.env``.

One pydantic-settings class; the API, the CLI, Alembic and the services all read it through
:func:`get_settings` or receive an instance explicitly (tests build their own).
"""
from __future__ import annotations

import re
import socket
from functools import lru_cache
from pathlib import Path
from typing import Annotated, Any, Literal, Optional
from urllib.parse import urlsplit

from pydantic import Field, SecretStr, ValidationError, field_validator, model_validator
from pydantic_settings import BaseSettings, NoDecode, SettingsConfigDict

from app.core.paths import PROJECT_ROOT
from app.geometry.pitch import BALL_DIAMETER_M, MIN_LINE_CLASSES, PLAY_VOLUME

#: Shortest ``V3D_SESSION_SECRET`` accepted (characters): 32 random URL-safe characters carry 192 bits.
MIN_SESSION_SECRET_CHARS = 32
#: Longest ``V3D_NODE_NAME`` (characters): it is stored in every job's owner (``node:pid:token``).
MAX_NODE_NAME_CHARS = 120
#: What ``V3D_STORAGE_URL`` accepts, as its refusal says.
STORAGE_URL_FORMS = "file:///ABSOLUTE/FOLDER or s3://BUCKET/PREFIX"
#: An S3 bucket's name (Amazon's rules, which S3-compatible stores follow): 3 to 63 lowercase letters, digits, dots and
#: hyphens, beginning and ending with a letter or digit.
_BUCKET = re.compile(r"^[a-z0-9][a-z0-9.-]{1,61}[a-z0-9]$")


class SettingsError(ValueError):
    """Settings from the environment v3d cannot run with: the message is one line naming each variable and what it
    accepts (``v3d`` prints it and exits 2, as Django's and Starlette's start-up checks refuse a setting in words)."""


def settings_error(exc: ValidationError) -> SettingsError:
    """The :class:`SettingsError` of a validation of :class:`Settings`: each failed setting as its variable
    (``V3D_NODE_NAME``) and what it accepts, never the value given (a setting may be a secret)."""
    lines = []
    for error in exc.errors(include_input=False, include_url=False):
        name = f"V3D_{str(error['loc'][0]).upper()}" if error["loc"] else "V3D_*"
        said = str(error["msg"]).removeprefix("Value error, ")
        lines.append(said if said.startswith(name) else f"{name}: {said}")
    return SettingsError("; ".join(lines))


def storage_url_problem(url: str) -> str | None:
    """What is wrong with ``url`` as ``V3D_STORAGE_URL``, in words, or None when it names a store: ``file:`` with an
    absolute folder and no host, or ``s3:`` with a bucket named by S3's rules (:data:`_BUCKET`) and an optional
    prefix; neither with a user, a query or a fragment."""
    parts = urlsplit(url)
    if parts.scheme not in ("file", "s3"):
        return "its scheme is neither file: nor s3:"
    if "@" in parts.netloc or parts.query or parts.fragment or any(not c.isprintable() for c in url):
        return "it holds a user, a query, a fragment or a character that cannot be printed"
    if parts.scheme == "file":
        if parts.netloc not in ("", "localhost"):
            return f"a file URL names a folder of this machine (file:///srv/v3d), not host {parts.netloc!r}"
        if not parts.path.startswith("/") or not parts.path.strip("/"):
            return "it names no absolute folder"
        return None
    if not parts.netloc:
        return "it names no bucket"
    if not _BUCKET.fullmatch(parts.netloc):
        return ("its bucket must be 3 to 63 lowercase letters, digits, dots and hyphens, beginning and ending with a "
                "letter or digit")
    if any(part in (".", "..") for part in parts.path.strip("/").split("/")):
        return "its prefix holds a '.' or '..' part"
    return None


#: The paper's choices where v3d's defaults differ (``V3D_PROFILE=paper``; an explicit ``V3D_*`` setting wins):
#: Eq. min_diametre's square box (v3d: the exact image of the sphere, ``exact_ray``; the monocular benchmark's
#: default estimator follows it, ``app.services.evaluation.monocular.default_estimator``) and no parallax filter
#: (v3d drops pairs whose rays meet below 2 degrees: near-duplicate viewpoints), and the optimised box as the detector
#: exports' ball box (v3d: the refined box where the 3D ball is well constrained), and the ball as the plain mean of
#: its kept pairs (``ball_rule`` "weights" without the parallax filter; v3d weighs the pairs by their evidence).
PAPER_PROFILE: dict[str, Any] = {"optimised_box_method": "paper", "min_parallax_deg": 0.0,
                                 "export_ball_box": "optimised", "ball_rule": "weights"}


#: The mark of a setting a system's stored rows are computed with (admission, 3D ball, pairs, reprojections, optimised
#: boxes, doubts), put in its ``Field``'s ``json_schema_extra`` where the setting is declared, so that a new such
#: setting is marked where it is written: the marked settings are :data:`DERIVED_SETTINGS`. The export's ball box is
#: chosen when exporting, not stored, and is not marked.
DERIVED: dict[str, Any] = {"derived": True}


class Settings(BaseSettings):
    """Service configuration.

    Environment variables: ``V3D_DATABASE_URL``, ``V3D_TRIANGULATION_TAU_PX`` and so on.
    """

    model_config = SettingsConfigDict(env_prefix="V3D_", env_file=".env", extra="ignore")

    profile: Literal["v3d", "paper"] = Field(
        "v3d",
        description="'paper' sets every choice where v3d's default differs from the paper (PAPER_PROFILE: the "
        "optimised box of Eq. min_diametre, hence the paper's monocular estimator, no parallax filter, the optimised "
        "box as the exports' ball box); a "
        "V3D_* setting given explicitly still wins. 'v3d': v3d's defaults (docs/configuration.md, 'The paper's "
        "settings in one switch').",
    )

    def derived_fingerprint(self) -> str:
        """16 hex digits naming the values of :data:`DERIVED_SETTINGS`: what a system's stored 3D ball, pairs,
        boxes and doubts were computed with (``System.derived_settings``); a profile or setting changed since makes
        them stale for ``v3d recompute`` (``app.services.derivation.recompute.systems_computed_otherwise``).

        >>> v3d, paper = Settings(_env_file=None), Settings(_env_file=None, profile="paper")
        >>> v3d.derived_fingerprint() == paper.derived_fingerprint()
        False
        """
        import hashlib
        import json

        values = json.dumps({k: getattr(self, k) for k in DERIVED_SETTINGS}, sort_keys=True)
        return hashlib.sha256(values.encode("utf-8")).hexdigest()[:16]

    @model_validator(mode="after")
    def _apply_profile(self) -> "Settings":
        """Under ``profile == "paper"``, :data:`PAPER_PROFILE`'s values for the settings not given explicitly."""
        if self.profile == "paper":
            for name, value in PAPER_PROFILE.items():
                if name not in self.model_fields_set:
                    object.__setattr__(self, name, value)
        return self

    database_url: str = Field(
        default=f"sqlite:///{PROJECT_ROOT / 'var' / 'v3d.sqlite3'}",
        description="SQLAlchemy URL; SQLite by default, postgresql+psycopg://... for teams.",
    )
    # --- multi-view system admission and triangulation (method.md sections 4 and 5) ---
    admit_jac_gamma: float = Field(0.005, description="gamma of the admission JaC (fraction of the diagonal).",
                                   json_schema_extra=DERIVED)
    admit_jac_min: float = Field(0.75, description="A frame joins triangulation when JaC@gamma > this.",
                                 json_schema_extra=DERIVED)
    triangulation_tau_px: float = Field(
        20.0,
        description=(
            "tau: a pair is kept when its error (see pair_error_rule) is below this, in px (with the default "
            "rule, px of a 1920-px-wide image: about the JaC@1% line tolerance). Chosen on the synthetic dev set "
            "(benchmarks/synthetic_ball.py): good pairs reach 9 px with true cameras and 23 px with a "
            "0.1-degree calibration error, pairs with a desynchronised, misplaced or mirror-calibrated view "
            "start at 22-23 px and mostly exceed 60 px; 20 keeps 80/81 good pairs and drops 12/12 bad ones "
            "at that calibration error."
        ),
        json_schema_extra=DERIVED,
    )
    pair_error_rule: Literal["max_scaled_1920", "mean_scaled_1920", "max_px"] = Field(
        "max_scaled_1920",
        description="How a pair's two reprojection errors combine into e_ij (see app.geometry.triangulation).",
        json_schema_extra=DERIVED,
    )
    min_baseline_m: float = Field(1.0, description="Pairs whose camera centres are closer are dropped (metres).",
                                  json_schema_extra=DERIVED)
    min_parallax_deg: float = Field(
        2.0,
        description="Pairs whose rays meet at a smaller angle are dropped (degrees). Beyond the paper: "
        "catches near-duplicate viewpoints whose calibrated centres drift more than 1 m apart. Replays "
        "of real broadcasts meet the main camera at 15 deg or more (5th percentile of the synthetic plan).",
        json_schema_extra=DERIVED,
    )
    ball_rule: Literal["weights", "evidence"] = Field(
        "evidence",
        description="How the pairs within tau make a system's stored 3D ball (app.services.derivation.recompute."
        "system_ball). 'evidence' (default): by uncertainty (app.geometry.evidence): every view whose camera fits "
        "most of its own lines takes part (admitted, or below admission with JaC@0.5 % of at least 0.5), the pairs "
        "weighed by their views' label and calibration pixel sigmas, a pair whose two cameras disagree on the "
        "players both views see left out, a pair beyond the others' joint sigma left out, a ball standing when its "
        "sigma is within ball_max_sigma_m and it lies in the play volume within three sigmas; no parallax filter, "
        "no veto by class. 'weights' (the rule before it, kept by V3D_PROFILE=paper): admitted views only, by class, "
        "the parallax filter (min_parallax_deg), the play volume on each pair's point and the calibration weights "
        "(a few-lined or unsure camera neither makes nor moves a ball alone). On 19 sets with truth, labels as "
        "imported, 'evidence' keeps more right 3D balls than the paper's rules on every set and at most half their "
        "balls more than 1 m off; after a pass of the fixes on 15 of 18 served measures (benchmarks/YIELD.md, "
        "2026-11-29).",
        json_schema_extra=DERIVED,
    )
    ball_max_sigma_m: float = Field(
        10.0, gt=0,
        description="Under ball_rule 'evidence', a 3D ball stands when its sigma (metres, one standard deviation "
        "along its least certain direction, from its views' label and calibration pixel sigmas) is within this. "
        "Large because the calibrations' stated pixel sigmas overstate their error (a camera fitted to few line "
        "classes states hundreds of px and is mostly off by a few): at 1 m it refuses about one right ball in ten. "
        "10 was chosen on dev-large and the two shared detector sets: of 5, 10, 25 and 50 m the largest that keeps "
        "at most half the paper's balls more than 1 m off on all three (benchmarks/YIELD.md, 2026-12-04). Every "
        "stored ball's sigma is shown whatever the rule.",
        json_schema_extra=DERIVED,
    )
    optimised_box_method: Literal["paper", "exact_ray", "exact_fused"] = Field(
        "exact_ray",
        description="How the optimised box is drawn (app.geometry.ball.optimise_box): 'paper' is Eq. "
        "min_diametre (square box of side d_opt on the annotated centre); 'exact_ray' is the exact image "
        "of the phi sphere at the same point of the annotated ray (an ellipse's box off-axis: size error "
        "0.08 % vs 1.4 % for 'paper' on the synthetic dev set with true cameras).",
        json_schema_extra=DERIVED,
    )
    ball_diameter_m: float = Field(BALL_DIAMETER_M, description="phi, the ball diameter in metres.",
                                   json_schema_extra=DERIVED)
    export_ball_box: Literal["refined", "optimised"] = Field(
        "refined", description="The ball box of the detector exports (YOLO, COCO) and the monocular benchmark's "
        "reference: 'refined' (v3d: the refined box where the 3D ball is well constrained, else the optimised box, "
        "else the annotated one; app.services.transfer.detector_export.ball_boxes) or 'optimised' (the paper: the "
        "optimised box, else the annotated one).")
    # --- doubts (app.geometry.doubts.DoubtSettings, built field by field by
    # app.services.derivation.doubts.doubt_settings: these doubt_* and the triangulation's settings above) ---
    # Chosen with benchmarks/doubts.py (synthetic dev + dev-large, v3d's own calibrations, PR plot).
    doubt_consensus_tau_px: float = Field(
        25.0,
        description="A labelled view is off the ball the other views agree on, and two views disagree, when its "
        "reprojection error exceeds this (px of a 1920-px-wide image). Every value from 8 to 30 catches all "
        "observable corrupted systems of the dev sets with the same single clean false alarm; 40 and above miss a "
        "desynchronised replay whose two-view error is 30-40 px. 25 stays above the triangulation's tau (a view "
        "it keeps is never accused) with room for real calibration error.",
        json_schema_extra=DERIVED,
    )
    doubt_near_duplicate_max_deg: float = Field(
        3.0,
        description="Two views that both show the ball are near duplicates when their camera centres subtend less "
        "than this angle at the ball (degrees). True near duplicates of the dev sets are within 0.6 deg, distinct "
        "viewpoints at least 10 deg apart; clean systems start to be flagged at 12 deg.",
        json_schema_extra=DERIVED,
    )
    doubt_inside_margin_px: float = Field(
        0.0,
        description="ball_missing needs the agreed ball to project at least this far inside the image (px at 1920 "
        "width; negative: that far outside). -40 calls an out-of-frame view; 0 to 40 change nothing on the dev sets.",
        json_schema_extra=DERIVED,
    )
    doubt_ground_box_tolerance: float = Field(
        0.35,
        description="With a single other labelled view, the ball goes on the grass along its ray when the box's "
        "monocular depth is within this relative difference of the grass depth (boxes err by about 19 % in size).",
        json_schema_extra=DERIVED,
    )
    doubt_max_ball_height_m: float = Field(
        PLAY_VOLUME.max_height_m, description="Highest ball the doubts count as agreement, metres above the grass "
        "(the play volume's height, app.geometry.pitch.PLAY_VOLUME, unless set).", json_schema_extra=DERIVED)
    doubt_mirror_rig_near_m: float = Field(
        1.0,
        description="An unflagged view is suspected mirrored when its ball ray meets another view's only mirrored "
        "and its mirrored camera stands within this of a known camera position of the game (metres) ...",
        json_schema_extra=DERIVED,
    )
    doubt_mirror_rig_gap_m: float = Field(
        2.0, description="... while as labelled it stands at least this much farther from every one (metres).",
        json_schema_extra=DERIVED,
    )
    doubt_detection_size_tolerance: float = Field(
        0.5, gt=0, lt=1, description="A detector's box is the ball's only when its diameter is within this relative "
        "difference of a 0.22 m ball's at the depth where the other views put it (app.geometry.doubts.detections). "
        "Set a priori, not fitted: detectors' box sides err by up to about 20 % and the depth by about as much.",
        json_schema_extra=DERIVED,
    )
    doubt_min_line_classes: int = Field(
        MIN_LINE_CLASSES,
        description="Views with fewer distinct field-line classes take no part in the doubt checks (info few_lines): "
        "rig cameras fitted to 2 classes reach JaC 1.0 yet turn the ball ray; 2 gives 9 clean false alarms of 233 "
        "on the dev sets, 3 and 4 one, 5 misses corrupted views.",
        json_schema_extra=DERIVED,
    )
    calibration_workers: int = Field(0, description="Processes for bulk calibration; 0 = all cores.")
    data_root: Optional[Path] = Field(
        None,
        description="Folder that imports over HTTP may read from (V3D_DATA_ROOT); a path outside it is refused "
        "(403) without saying whether it exists. None: HTTP imports of server paths are refused (the CLI, run by "
        "the machine's owner, is not confined).",
    )
    # --- users and sessions (app.api.authentication, app.services.accounts.users) ---
    session_secret: Optional[SecretStr] = Field(
        None,
        description="Key that signs the browser's session cookies (V3D_SESSION_SECRET), at least "
        "32 characters (e.g. `python -c 'import secrets; print(secrets.token_urlsafe(48))'`). None: the key "
        "generated once in the database (table server_secrets), shared by every worker and kept across restarts.",
    )
    login_max_failures_per_name: int = Field(10, gt=0, description="Failed logins of one name from one client "
                                                                    "address per window before 429 "
                                                                    "(V3D_LOGIN_MAX_FAILURES_PER_NAME).")
    login_max_failures_per_address: int = Field(50, gt=0, description="Failed logins from one client address per "
                                                                       "window before 429 "
                                                                       "(V3D_LOGIN_MAX_FAILURES_PER_ADDRESS).")
    login_window_s: int = Field(300, gt=0, description="The window of the failed-login limits (seconds).")
    trusted_proxies: list[str] = Field(
        default_factory=list, description="Reverse proxies (addresses or networks, JSON list) whose X-Forwarded-For "
        "names the client of a request (V3D_TRUSTED_PROXIES); otherwise the client is the socket peer.")
    allowed_hosts: Annotated[list[str], NoDecode] = Field(
        default_factory=list, description="Host names (or addresses) this server is reached by besides the loopback "
        "ones (localhost, 127.0.0.1, [::1]), comma-separated, any port; '*.example.org' names a domain's hosts "
        "(V3D_ALLOWED_HOSTS). A request naming another Host gets 400: a web page cannot reach the server by a name "
        "of its own that resolves here (DNS rebinding). Name the host the users type, e.g. v3d.example.org.")
    secure_cookies: bool = Field(
        False, description="Send the session cookie with Secure (HTTPS only): set it behind TLS (V3D_SECURE_COOKIES).",
    )
    session_max_age_s: int = Field(
        12 * 3600, gt=0, description="A browser session ends this long after its login (seconds).",
    )

    # --- serving ---
    gc_young_threshold: int = Field(
        20_000, ge=0, description="The garbage collector's young-generation threshold in a server process "
        "(gc.set_threshold(n, 10, 10); 0 keeps Python's default, 700). A full collection of a server's objects "
        "takes 0.2-0.4 s on the 2-core machine and, at the default, falls in about one edit in 20 (an edit's ORM "
        "objects outlive young collections); 20,000 makes full collections ~30x rarer "
        "(python -m benchmarks.issia_service --gc-threshold N shows the effect).")
    # --- the server's edge (app.cli.serve.server_options, app.api.edge) ---
    max_header_kb: float = Field(
        32.0, gt=0, description="Largest request line and headers of one request together (KB, 2^10 bytes): a "
        "larger head is answered 400 and its connection closed as soon as this much has arrived, before it is "
        "parsed further (uvicorn's h11 parser, h11_max_incomplete_event_size; V3D_MAX_HEADER_KB).")
    max_header_count: int = Field(
        100, gt=0, description="Most header lines one request may carry: 431 beyond it, before any route "
        "(V3D_MAX_HEADER_COUNT).")
    keep_alive_s: int = Field(
        5, gt=0, description="An idle connection between two requests is closed after this many seconds "
        "(uvicorn's timeout_keep_alive; V3D_KEEP_ALIVE_S).")
    send_timeout_s: float = Field(
        30.0, gt=0, description="A client that takes no piece of an answer for this long (seconds) is disconnected: "
        "answers leave in pieces of 64 KiB, each waiting for the client to read the one before, so a client that "
        "never reads holds at most a piece or two of the server's memory, and not for longer than this "
        "(V3D_SEND_TIMEOUT_S).")
    max_answer_kb: int = Field(
        1024, gt=0, description="Most JSON one page of the audit log may carry (KB): the page stops before the entry "
        "that would pass it (one entry at least) and names the offset of the next page (next_offset), so that "
        "entries of large before and after states never make an answer of megabytes (V3D_MAX_ANSWER_KB).")
    compute_share: int = Field(
        2, gt=0, description="How many calibration previews and evaluations one user may have computing at once in "
        "one server process: one more is answered 429 with Retry-After at once, so that one user's parallel "
        "requests take no more than their share of the process's threads and cores; edits are not counted "
        "(V3D_COMPUTE_SHARE).")

    # --- background jobs and uploads (app.services.jobs.runner, app.services.transfer.archives) ---
    import_batch_frames: int = Field(
        2000, gt=0, description="An import is stored in transactions of whole games of about this many frames: memory "
        "stays bounded by a batch, and a killed import leaves whole games stored (completed by running it again).")
    job_runner: bool = Field(
        True, description="Each server process runs queued jobs (imports, recomputes, exports) in a thread of its "
        "own; off, jobs wait for another process (v3d jobs run, or a server).")
    job_poll_seconds: float = Field(1.0, gt=0, description="How often an idle runner looks for a queued job (s).")
    job_heartbeat_seconds: float = Field(1.0, gt=0, description="How often a running job's process beats and "
                                                                "stores its progress (s).")
    job_stale_seconds: float = Field(
        120.0, gt=0, description="A running job whose heartbeat is older than this is taken over and resumed by "
        "another runner, of any node (s); on its own node (V3D_NODE_NAME) a job whose process is gone is taken over "
        "at once. Above the "
        "longest write transaction of an import batch, during which SQLite holds the heartbeat back.")
    node_name: Optional[str] = Field(
        None,
        description="This node's name in the owner of the jobs it runs (``node:pid:token``); None: the host name "
        "(:func:`node_name`). "
        "Nodes sharing one database need distinct names: a node checks whether a job's process is gone only for its "
        "own jobs; another node's job is taken over when its heartbeat is older than V3D_JOB_STALE_SECONDS, and its "
        "live progress is read from the job's row. No colon or space.")
    jobs_dir: Optional[Path] = Field(
        None, description="Where uploads are unpacked (uploads/) and export jobs write their files (exports/); "
        "default: jobs/ beside a SQLite database file, else var/jobs in the checkout.")
    storage_url: Optional[str] = Field(
        None, description="Where every file v3d keeps lies (uploads, frame images and archives, export results): "
        "file:///FOLDER, or s3://BUCKET/PREFIX through boto3 with the standard AWS variables (AWS_ACCESS_KEY_ID, "
        "AWS_SECRET_ACCESS_KEY, AWS_DEFAULT_REGION, and AWS_ENDPOINT_URL for an S3-compatible store; the bucket "
        "must exist). Nodes that share it and the database share everything; the jobs folder is then only each "
        "node's scratch. None: the jobs folder itself (file://<jobs dir>, one machine) (V3D_STORAGE_URL).")
    store_timeout_s: float = Field(
        5.0, gt=0, le=300, description="How long a request to an S3 store waits for its answer (s; to connect, at most "
        "3 s); a request is sent twice at most, so a store that never answers fails a request, answered 503, within "
        "about twice this (V3D_STORE_TIMEOUT_S).")
    export_keep_hours: float = Field(
        24.0, gt=0, description="How long the file an export job wrote is kept for download (hours, from when it was "
        "written): older export files under <jobs dir>/exports are removed when an export job starts or a file is "
        "asked for (then 404).")
    backups_kept: int = Field(
        7, ge=1, description="How many archives of backup jobs (POST /api/backups) the store keeps: the oldest are "
        "removed once a new one is complete; a new one is refused (409) while the disk has less room than the last "
        "one took (V3D_BACKUPS_KEPT).")
    restore_max_line_mb: float = Field(
        64.0, gt=0, description="Longest table row a restore reads from an archive (MB, 2^20 bytes: one line of a "
        "tables/*.jsonl member, a release document the largest): a longer one refuses the restore (exit 2) at its "
        "byte past the bound, so an archive's rows never hold more memory than this (V3D_RESTORE_MAX_LINE_MB).")
    restore_spare_mb: float = Field(
        256.0, ge=0, description="Free space a restore leaves on the disk of a folder store and of a SQLite database "
        "(MB): an archive whose files and rows, at the sizes its manifest declares, do not fit with this much to "
        "spare is refused before anything is written (V3D_RESTORE_SPARE_MB).")
    remote_timeout_s: float = Field(
        15.0, gt=0, le=3600, description="The longest one request of a remote command (v3d --server) may take, its "
        "answer read whole (s; a read begun just before the end waits at most half of it more; an upload's body and "
        "an export's download excepted, each of their reads bounded by half of it): a server answering a byte at a "
        "time, or never ending its body, fails the command with one Error: line (V3D_REMOTE_TIMEOUT_S).")
    remote_max_answer_mb: float = Field(
        64.0, gt=0, description="The longest answer a remote command (v3d --server) reads into memory (MB, 2^20 "
        "bytes): a longer one fails the command with one Error: line at its first byte past "
        "(V3D_REMOTE_MAX_ANSWER_MB).")
    max_json_kb: float = Field(1024.0, gt=0, description="Largest request body that is not an upload (JSON), in KB "
                                                       "(2^10 bytes): 413 before it is parsed (V3D_MAX_JSON_KB).")
    max_upload_mb: float = Field(2048.0, gt=0, description="Largest upload accepted (MB, 2^20 bytes), counted while "
                                                            "it is written to disk: 413 beyond it.")
    max_unpacked_mb: float = Field(
        8192.0, gt=0, description="Largest total uncompressed size of an uploaded zip's members, nested image "
        "zips included (MB): a zip bomb is refused (400) before anything is extracted.")
    max_upload_members: int = Field(200_000, gt=0, description="Most members an uploaded zip may hold (nested "
                                                                "image zips included).")
    max_zip_ratio: float = Field(
        100.0, gt=1, description="Most bytes an uploaded zip's member, or the whole zip (nested zips too), may unpack "
        "to per byte it packs, beyond its first MiB: checked from the zip's directory and counted again while it "
        "unpacks; a zip bomb is refused (400; 422 for the monocular benchmark's predictions).")
    max_predictions_mb: float = Field(
        64.0, gt=0, description="Largest predictions upload of the monocular benchmark (a zip of YOLO files or a COCO "
        "results JSON, MB): 413 as soon as that much of the body has arrived (never spooled beyond it); the COCO file "
        "is read as a stream. Each YOLO .txt may hold 1 MiB (app.geometry.metrics) and data.yaml 64 KiB "
        "(app.services.evaluation.monocular).")
    max_prediction_import_mb: float = Field(
        256.0, gt=0, description="Largest upload of a detector's predictions to import (POST /api/imports kind "
        "predictions: a zip holding one CSV, MB): 413 beyond it. The CSV is read as a stream, so its size bounds the "
        "import's time, not its memory.")
    max_image_pixels: int = Field(
        50_000_000, gt=0, description="Most pixels (width x height) an imported image or video frame may have, read "
        "from its header before anything is decoded: a larger one refuses the import (400 / exit 2) naming it.")
    max_image_mb: float = Field(
        256.0, gt=0, description="Most bytes an imported image file or zip member may have (MB, 2^20 bytes; a "
        "50-megapixel PNG compresses well below the default): a larger one refuses the import (400 / exit 2) naming "
        "the file and this setting, so that what is kept and served costs at most that much to read, streamed.")

    max_line_points_per_frame: int = Field(
        2000, gt=0, description="Most field-line points one edit may give a view (all its classes and polylines "
        "together): a larger PUT .../field-lines is refused with 422 naming the field 'lines' before any geometry "
        "runs (the real SoccerNet-calibration frames have at most 61 (sn22) and 71 (wc14)). Lines stored before the "
        "cap still open, calibrate and mirror (V3D_MAX_LINE_POINTS_PER_FRAME).")
    max_views_per_system: int = Field(
        16, gt=0, description="Most views (action and replays) an imported system may have: a system with more is "
        "left out of the import, which names it and the count in its report (skipped_systems); the rest of the "
        "dataset imports. Pairwise work grows with the square of the views. Systems stored before the cap still "
        "open and edit (V3D_MAX_VIEWS_PER_SYSTEM).")
    max_passes_per_user: int = Field(
        50, gt=0, description="Most review passes kept per user (each stores the ids of every system of its queue): "
        "beginning one more drops that user's least recently visited passes beyond it, in the same transaction "
        "(V3D_MAX_PASSES_PER_USER).")
    # ----- bounds on what one user's input may make the others read: a detector's predictions, comments -----
    max_predictions_per_frame: int = Field(
        16, gt=0, description="Most detector predictions a frame keeps, all sources together, the best by score (what "
        "the doubts' check of detections considers per view): an import keeps, on each frame, its best predictions in "
        "the room the other sources leave and counts the rest in its report (dropped); every read (a system's "
        "recomputation, its doubts, the monocular benchmark, a YOLO or COCO file read) takes at most this many per "
        "frame or image, the best by score, also from a database written before the cap "
        "(V3D_MAX_PREDICTIONS_PER_FRAME). A lower cap reaches the stored doubts at their system's next "
        "recomputation (v3d recompute).")
    max_players_per_frame: int = Field(
        200, gt=0, description="Most player boxes an import keeps a frame, the first in the file's order (a real "
        "frame boxes a few dozen people; they only help place the cameras the lines cannot): the rest are counted in "
        "the import's report and not stored (V3D_MAX_PLAYERS_PER_FRAME).")
    max_comments_per_system: int = Field(
        300, gt=0, description="Most comments one system may hold, resolved ones included: one more is refused with "
        "409 naming the cap (V3D_MAX_COMMENTS_PER_SYSTEM).")
    # ----- end of the bounds on predictions and comments -----
    write_lock_timeout_s: float = Field(
        5.0, gt=0, description="How long a served request waits for the database's write lock (SQLite's busy "
        "timeout; PostgreSQL's lock_timeout on the row locks of an edit) before it is answered 503 with Retry-After "
        "(V3D_WRITE_LOCK_TIMEOUT_S). Edits compute their geometry before they take the lock and hold it only to "
        "compare and write (app.services.curation.editing), so a wait beyond a few seconds means the database is "
        "overloaded, not that another edit is computing.")
    edit_slots: int = Field(
        1, ge=0, description="How many edits that recompute their system (ball, field lines, mirror, exclusion, and "
        "their undos and reverts) compute at once in one server process; 0: no limit (V3D_EDIT_SLOTS). An edit's "
        "geometry and ORM work hold Python's GIL, so two such edits in one process only share its core: each takes "
        "twice as long, the window in which a sibling edit of the same system commits first (and forces a second "
        "computation) doubles, and an edit holding the write lock is slowed by the others, while the other processes "
        "wait for the lock. Run more processes (v3d serve --workers) for more edits at once.")
    edit_slot_wait_s: float = Field(
        0.5, ge=0, description="How long an edit waits for a slot (edit_slots) before it computes anyway, beside the "
        "slots' edits (seconds; V3D_EDIT_SLOT_WAIT_S): an edit with a long geometry (a line edit at the point cap) "
        "delays the edits of its process by at most this.")
    @field_validator("allowed_hosts", mode="before")
    @classmethod
    def _comma_separated_hosts(cls, value: Any) -> Any:
        """``V3D_ALLOWED_HOSTS=a.example,b.example`` (or a JSON list): the names, stripped and lower case."""
        if isinstance(value, str):
            text = value.strip()
            if text.startswith("["):
                import json

                value = json.loads(text)
            else:
                value = text.split(",")
        if isinstance(value, (list, tuple)):
            names = [str(v).strip().lower() for v in value if str(v).strip()]
            for name in names:
                if "*" in name[1:] or (name.startswith("*") and name != "*" and not name.startswith("*.")):
                    raise ValueError(f"V3D_ALLOWED_HOSTS: {name!r}: a wildcard names a domain's hosts, as "
                                     "'*.example.org'")
            # an IPv6 address is written in brackets in a Host header
            return [f"[{n}]" if ":" in n and not n.startswith("[") else n for n in names]
        return value

    @field_validator("storage_url")
    @classmethod
    def _storage_url_scheme(cls, value: Optional[str]) -> Optional[str]:
        """``file:///FOLDER`` or ``s3://BUCKET/PREFIX``, refused at start-up otherwise in words naming the variable
        and what it accepts (:func:`storage_url_problem`)."""
        if value is None:
            return None
        problem = storage_url_problem(value)
        if problem is not None:
            raise ValueError(f"V3D_STORAGE_URL must be {STORAGE_URL_FORMS}: {problem}")
        return value

    @field_validator("node_name")
    @classmethod
    def _node_name_words(cls, value: Optional[str]) -> Optional[str]:
        """1 to :data:`MAX_NODE_NAME_CHARS` printable characters, no colon (the owner's separator) and no space."""
        if value is not None and (not 0 < len(value) <= MAX_NODE_NAME_CHARS
                                  or any(c == ":" or c.isspace() or not c.isprintable() for c in value)):
            raise ValueError(f"V3D_NODE_NAME must be 1 to {MAX_NODE_NAME_CHARS} printable characters without a "
                             "colon or a space (it names this node in its jobs' owners, node:pid:token)")
        return value

    @field_validator("session_secret")
    @classmethod
    def _session_secret_long_enough(cls, value: Optional[SecretStr]) -> Optional[SecretStr]:
        """A cookie-signing key short enough to guess is refused at start-up, naming the variable."""
        if value is not None and len(value.get_secret_value()) < MIN_SESSION_SECRET_CHARS:
            raise ValueError(f"V3D_SESSION_SECRET must be at least {MIN_SESSION_SECRET_CHARS} characters (it signs "
                             "every browser session); unset it to use the key kept in the database")
        return value


#: The settings a system's stored rows are computed with (every setting marked :data:`DERIVED` where it is declared),
#: in declaration order: their values' fingerprint is stored with each system (``Settings.derived_fingerprint``).
DERIVED_SETTINGS: tuple[str, ...] = tuple(
    name for name, f in Settings.model_fields.items()
    if isinstance(f.json_schema_extra, dict) and f.json_schema_extra.get("derived"))


def var_dir(settings: Settings, name: str) -> Path:
    """The folder ``name`` where v3d keeps files of its own (the demo dataset, uploads, export files):
    beside a SQLite database file, else under ``var/`` of the checkout. Not created here."""
    from sqlalchemy.engine import make_url

    url = make_url(settings.database_url)
    if url.get_backend_name() == "sqlite" and url.database not in (None, "", ":memory:"):
        return Path(url.database).expanduser().resolve().parent / name
    return PROJECT_ROOT / "var" / name


def node_name(settings: Settings) -> str:
    """``settings.node_name``, else this machine's host name: the node part of the jobs' owners
    (``app.services.jobs.runner.owner_name``)."""
    return settings.node_name if settings.node_name is not None else socket.gethostname()


def jobs_dir(settings: Settings) -> Path:
    """``settings.jobs_dir``, else :func:`var_dir` ``jobs``."""
    return settings.jobs_dir if settings.jobs_dir is not None else var_dir(settings, "jobs")


@lru_cache
def get_settings() -> Settings:
    """The process-wide settings read from the environment.

    Raises:
        SettingsError: a variable holds a value v3d cannot run with (:func:`settings_error`)."""
    try:
        return Settings()
    except ValidationError as exc:
        raise settings_error(exc) from None
