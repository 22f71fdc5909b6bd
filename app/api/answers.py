"""Answers of the hot routes (the system page and every edit's recomputed system view) serialised where they are
made.

A synchronous FastAPI route that returns a pydantic model has it validated again (``serialize_response``: one more
hop through the thread pool) and then serialised on the event loop, whose one thread every request shares. The
routes that answer the system view, the largest and most frequent answer, instead return the JSON bytes made in
their own worker thread by the model's own serializer (the bytes FastAPI would send: the same serializer, by alias),
with the headers the route set on its ``Response`` parameter (ETag, audit entry). The route keeps its
``response_model``, so the OpenAPI schema and ``/docs`` are unchanged (an edit's answer).
"""
from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import orjson
from fastapi import Response
from pydantic import BaseModel


def json_answer(model: BaseModel, response: Response) -> Response:
    """``model`` as a JSON answer (``application/json``, serialised by alias as FastAPI's ``response_model`` would),
    carrying the headers and status code set on ``response``, the route's ``Response`` parameter."""
    out = Response(content=model.__pydantic_serializer__.to_json(model, by_alias=True), media_type="application/json")
    out.headers.raw.extend(response.headers.raw)
    if response.status_code:
        out.status_code = response.status_code
    return out


def capped_json(batches: Iterable[Sequence[BaseModel]], max_bytes: float) -> list[bytes]:
    """The JSON of each item of ``batches`` (serialised by alias), in order, until the next one would take the total
    past ``max_bytes`` (the first is always kept): a list answer whose items are of any size stays within a byte cap.
    The batches are read only as far as needed (the caller's iterator may read them from the database lazily)."""
    out: list[bytes] = []
    size = 0
    for batch in batches:
        for item in batch:
            piece = item.__pydantic_serializer__.to_json(item, by_alias=True)
            if out and size + len(piece) > max_bytes:
                return out
            out.append(piece)
            size += len(piece) + 1
    return out


def json_items(items: list[bytes], fields: dict[str, Any]) -> Response:
    """A JSON answer ``{"items": [...], **fields}`` of items serialised already (:func:`capped_json`)."""
    head = b'{"items":[' + b",".join(items) + b"],"
    return Response(content=head + orjson.dumps(fields)[1:], media_type="application/json")
