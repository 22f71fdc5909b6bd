"""Settings of the service, read from the environment (prefix ``V3D_``) and ``.env``.

One pydantic-settings class; the API, the CLI, Alembic and the services all read it through
:func:`get_settings` or receive an instance explicitly (tests build their own).
"""
from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from typing import Literal, Optional

from pydantic import Field
from pydantic_settings import BaseSettings, SettingsConfigDict

from app.core.paths import PROJECT_ROOT


class Settings(BaseSettings):
    """Service configuration.

    Environment variables: ``V3D_DATABASE_URL``, ``V3D_TRIANGULATION_TAU_PX`` and so on.
    """

    model_config = SettingsConfigDict(env_prefix="V3D_", env_file=".env", extra="ignore")

    database_url: str = Field(
        default=f"sqlite:///{PROJECT_ROOT / 'var' / 'v3d.sqlite3'}",
        description="SQLAlchemy URL; SQLite by default, postgresql+psycopg://... for teams.",
    )
    # --- multi-view system admission and triangulation (method.md sections 4 and 5) ---
    admit_jac_gamma: float = Field(0.005, description="gamma of the admission JaC (fraction of the diagonal).")
    admit_jac_min: float = Field(0.75, description="A frame joins triangulation when JaC@gamma > this.")
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
    )
    pair_error_rule: Literal["max_scaled_1920", "mean_scaled_1920", "max_px"] = Field(
        "max_scaled_1920",
        description="How a pair's two reprojection errors combine into e_ij (see app.geometry.triangulation).",
    )
    min_baseline_m: float = Field(1.0, description="Pairs whose camera centres are closer are dropped (metres).")
    min_parallax_deg: float = Field(
        2.0,
        description="Pairs whose rays meet at a smaller angle are dropped (degrees). Beyond the paper: "
        "catches near-duplicate viewpoints whose calibrated centres drift more than 1 m apart. Replays "
        "of real broadcasts meet the main camera at 15 deg or more (5th percentile of the synthetic plan).",
    )
    optimised_box_method: Literal["paper", "exact_ray", "exact_fused"] = Field(
        "exact_ray",
        description="How the optimised box is drawn (app.geometry.ball.optimise_box): 'paper' is Eq. "
        "min_diametre (square box of side d_opt on the annotated centre); 'exact_ray' is the exact image "
        "of the 0.22 m sphere at the same point of the annotated ray (an ellipse's box off-axis: size error "
        "0.08 % vs 1.4 % for 'paper' on the synthetic dev set with true cameras).",
    )
    ball_diameter_m: float = Field(0.22, description="phi, the ball diameter in metres.")
    # --- doubts (app.geometry.doubts.DoubtSettings: field f is read from doubt_f, else from f) ---
    # Chosen with benchmarks/doubts.py (synthetic dev + dev-large, v3d's own calibrations, PR plot).
    doubt_consensus_tau_px: float = Field(
        25.0,
        description="A labelled view is off the ball the other views agree on, and two views disagree, when its "
        "reprojection error exceeds this (px of a 1920-px-wide image). Every value from 8 to 30 catches all "
        "observable corrupted systems of the dev sets with the same single clean false alarm; 40 and above miss a "
        "desynchronised replay whose two-view error is 30-40 px. 25 stays above the triangulation's tau (a view "
        "it keeps is never accused) with room for real calibration error.",
    )
    doubt_near_duplicate_max_deg: float = Field(
        3.0,
        description="Two views that both show the ball are near duplicates when their camera centres subtend less "
        "than this angle at the ball (degrees). True near duplicates of the dev sets are within 0.6 deg, distinct "
        "viewpoints at least 10 deg apart; clean systems start to be flagged at 12 deg.",
    )
    doubt_inside_margin_px: float = Field(
        0.0,
        description="ball_missing needs the agreed ball to project at least this far inside the image (px at 1920 "
        "width; negative: that far outside). -40 calls an out-of-frame view; 0 to 40 change nothing on the dev sets.",
    )
    doubt_single_view_margin_px: float = Field(
        40.0,
        description="With a single other labelled view the ball's depth along its ray is uncertain: ball_missing "
        "needs it at least this far inside the image (px at 1920 width). 0 calls an out-of-frame view whose ball "
        "lies just past the border; 100 loses a missing ball near the border.",
    )
    doubt_ground_box_tolerance: float = Field(
        0.35,
        description="With a single other labelled view, the ball goes on the grass along its ray when the box's "
        "monocular depth is within this relative difference of the grass depth (boxes err by about 19 % in size).",
    )
    doubt_max_ball_height_m: float = Field(30.0, description="Highest plausible placed ball, metres above the grass.")
    doubt_mirror_rig_near_m: float = Field(
        1.0,
        description="An unflagged view is suspected mirrored when its ball ray meets another view's only mirrored "
        "and its mirrored camera stands within this of a known camera position of the game (metres) ...",
    )
    doubt_mirror_rig_gap_m: float = Field(
        2.0, description="... while as labelled it stands at least this much farther from every one (metres).",
    )
    doubt_min_line_classes: int = Field(
        4,
        description="Views with fewer distinct field-line classes take no part in the doubt checks (info few_lines): "
        "rig cameras fitted to 2 classes reach JaC 1.0 yet turn the ball ray; 2 gives 9 clean false alarms of 233 "
        "on the dev sets, 3 and 4 one, 5 misses corrupted views.",
    )
    calibration_workers: int = Field(0, description="Processes for bulk calibration; 0 = all cores.")
    data_root: Optional[Path] = Field(
        None,
        description="Folder that imports over HTTP may read from (V3D_DATA_ROOT); a path outside it is refused "
        "(403) without saying whether it exists. None: HTTP imports of server paths are refused (the CLI, run by "
        "the machine's owner, is not confined).",
    )


@lru_cache
def get_settings() -> Settings:
    """The process-wide settings read from the environment."""
    return Settings()
