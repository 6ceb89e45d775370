"""Reading what evpipe's programs print, shared by the tools/ scripts that run them (pose_results.py,
bench_pipeline.py, bench_denoise.py): the one-object-per-line JSON of --json / --metrics, a failure type with the
reason, and the machine a measurement ran on."""

from __future__ import annotations

import json
import os


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


def machine() -> str:
    """Host, cores and CPU model: absolute speeds (Mev/s) are only comparable on the same CPU."""
    model = "unknown CPU"
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for ln in f:
                if ln.startswith("model name"):
                    model = ln.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return f"{os.uname().nodename}, {os.cpu_count()} cores, {model}"
