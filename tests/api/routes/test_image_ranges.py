"""``GET /api/frames/{id}/image`` with ``Range``: one byte range of a zip member or a file (206, ``Content-Range``),
416 beyond its end, the whole image when ``If-Range`` names another version or the header is not one range."""
from __future__ import annotations

import pytest
from fastapi.testclient import TestClient

from ..factories import Scene, png_bytes

# Served: ranges of stored bytes: the same on either engine, so not an ``engine`` module.
pytestmark = pytest.mark.served


@pytest.mark.parametrize("view_index", [0, 1], ids=["zip-member", "file"])
def test_a_byte_range_of_an_image(client: TestClient, scene: Scene, view_index: int) -> None:
    url = client.get(f"/api/systems/{scene.system_id}").json()["views"][view_index]["image_url"]
    whole = png_bytes()
    full = client.get(url)
    assert full.headers["accept-ranges"] == "bytes" and full.content == whole
    part = client.get(url, headers={"Range": "bytes=8-23"})
    assert part.status_code == 206 and part.content == whole[8:24]
    assert part.headers["content-range"] == f"bytes 8-23/{len(whole)}" and part.headers["content-length"] == "16"
    tail = client.get(url, headers={"Range": "bytes=-12"})
    assert tail.status_code == 206 and tail.content == whole[-12:]
    beyond = client.get(url, headers={"Range": f"bytes={len(whole)}-"})
    assert beyond.status_code == 416 and beyond.headers["content-range"] == f"bytes */{len(whole)}"
    other = client.get(url, headers={"Range": "bytes=8-23", "If-Range": '"another-version"'})
    assert other.status_code == 200 and other.content == whole
    same = client.get(url, headers={"Range": "bytes=8-23", "If-Range": full.headers["etag"]})
    assert same.status_code == 206 and same.content == whole[8:24]
    assert client.get(url, headers={"Range": "bytes=0-1,4-5"}).content == whole  # several ranges: the whole
