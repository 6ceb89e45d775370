"""Reading what evpipe's programs print, shared by the tools/ scripts that run them (pose_results.py,
bench_pipeline.py): the one-object-per-line JSON of --json / --metrics and a failure type with the reason."""

from __future__ import annotations

import json


class Failure(Exception):
    """A run or a tool failed; the message says which and why."""


def last_line(text: str) -> str:
    lines = [ln for ln in text.strip().splitlines() if ln.strip()]
    return lines[-1] if lines else ""


def json_object(text: str, what: str) -> dict:
    """The last line of `text` that is a JSON object (evpipe's tools print one object on a line)."""
    for ln in reversed(text.strip().splitlines()):
        ln = ln.strip()
        if ln.startswith("{"):
            try:
                return json.loads(ln)
            except json.JSONDecodeError as e:
                raise Failure(f"{what}: bad JSON ({e}): {ln[:200]}")
    raise Failure(f"{what}: no JSON object in its output: {text.strip()[:200]!r}")
