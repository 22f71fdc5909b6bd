"""v3d_client: the Python client of a v3d server's REST API (``docs/client.md``)::

    from v3d_client import Client

    with Client.from_env() as v3d:  # V3D_URL, V3D_TOKEN
        for system in v3d.systems(doubt="mirrored_labels"):
            print(system.id, system.name)

Depends on httpx and pydantic only: it imports nothing of the server (``app``) and nothing of numpy or scipy.
"""
from v3d_client.client import LEFT_OUT, ROUTES, Client
from v3d_client.errors import (
    AnswerTooLarge,
    AnswerTooSlow,
    APIError,
    BadAnswer,
    BadRequest,
    Busy,
    Conflict,
    EditConflict,
    Forbidden,
    Invalid,
    JobFailed,
    JobTimeout,
    NotFound,
    NotJSON,
    PreconditionRequired,
    Redirected,
    ServerError,
    TooLarge,
    Unauthorized,
    Unreachable,
    V3DError,
    VersionMismatch,
    WrongShape,
)
from v3d_client.models import (
    Annotator,
    AuditEntry,
    Batch,
    BatchAcceptance,
    Comment,
    Decision,
    Doubt,
    Frame,
    Game,
    Job,
    PredictionSource,
    Release,
    ReleaseDiff,
    Stats,
    System,
    SystemSummary,
    Token,
    User,
    View,
)
from v3d_client.version import __version__

__all__ = [
    "APIError", "Annotator", "AnswerTooLarge", "AnswerTooSlow", "AuditEntry", "BadAnswer", "BadRequest", "Batch",
    "BatchAcceptance", "Busy", "Client", "Comment", "Conflict", "Decision", "Doubt", "EditConflict", "Forbidden",
    "Frame", "Game", "Invalid", "Job", "JobFailed", "JobTimeout", "LEFT_OUT", "NotFound", "NotJSON",
    "PreconditionRequired", "PredictionSource", "ROUTES", "Redirected", "Release", "ReleaseDiff", "ServerError",
    "Stats", "System", "SystemSummary", "Token", "TooLarge", "Unauthorized", "Unreachable", "User", "V3DError",
    "VersionMismatch", "View", "WrongShape", "__version__",
]
