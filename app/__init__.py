"""v3d: multi-view soccer broadcast annotations to reviewed 3D ball labels (the SoccerNet-v3D method).

``__version__`` is the server's version: the OpenAPI document's and ``GET /api/health``'s, and the version of the
client package that ships beside it (``clients/python``, ``v3d_client.version``), which refuses a server of another
series at its first call.
"""

__version__ = "0.1.0"
