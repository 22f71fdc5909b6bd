"""Settings of the service, read from the environment (prefix ``V3D_``) and ``.env``.

One pydantic-settings class; the API, the CLI, Alembic and the services all read it through
:func:`get_settings` or receive an instance explicitly (tests build their own).
"""
from __future__ import annotations

from functools import lru_cache
from typing import Literal

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
    calibration_workers: int = Field(0, description="Processes for bulk calibration; 0 = all cores.")


@lru_cache
def get_settings() -> Settings:
    """The process-wide settings read from the environment."""
    return Settings()
