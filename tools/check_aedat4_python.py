#!/usr/bin/env python3
"""Checks evpipe's AEDAT 4.0 writer against two independent readers.

For each compression (lz4, zstd, none) it writes IN as AEDAT 4.0 with `evconvert IN OUT.aedat4
--compression C`, reads OUT with dv-processing (MonoCameraRecording) and with the `aedat` package, and
compares event for event with evpipe's own text output of IN (`evconvert IN REF.txt`). It also checks the
resolution both readers report and dv-processing's time range (which comes from the file data table).

IN defaults to ../shared/data/real/emlb-demo-01/demo-01.aedat4, or a synthetic text recording when that is
absent. Exit status: 0 identical, 1 with a message on any difference or failure, 77 "skipped: <why>" when
evconvert or the Python packages are not available.

  tools/check_aedat4_python.py [--build DIR | --evconvert PATH] [--input FILE] [--keep DIR]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import evpipe_pyenv  # noqa: E402

evpipe_pyenv.ensure_packages(["dv_processing", "numpy", "aedat"])

import aedat  # noqa: E402
import dv_processing as dv  # noqa: E402
import numpy as np  # noqa: E402


def fail(msg: str) -> None:
    print(f"FAIL: {msg}")
    sys.exit(1)


def run(cmd: list[str]) -> None:
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        fail(f"{' '.join(cmd)} exited with {r.returncode}: {r.stderr.strip()}")


def read_text(path: Path) -> tuple[np.ndarray, tuple[int, int] | None]:
    """evpipe text output: '# width=W height=H' comment, then 't x y p [label]' lines."""
    size = None
    with open(path) as f:
        for line in f:
            if not line.startswith("#"):
                break
            fields = dict(kv.split("=", 1) for kv in line[1:].split() if "=" in kv)
            if "width" in fields and "height" in fields:
                size = (int(fields["width"]), int(fields["height"]))
    cols = np.loadtxt(path, comments="#", dtype=np.int64, ndmin=2)
    if cols.size == 0:
        cols = np.zeros((0, 4), dtype=np.int64)
    return cols[:, :4], size


def synthetic_text(path: Path, n: int = 200_000) -> None:
    rng = np.random.default_rng(7)
    t = 1_600_000_000_000_000 + np.cumsum(rng.integers(0, 40, n))
    cols = np.stack([t, rng.integers(0, 346, n), rng.integers(0, 260, n), rng.integers(0, 2, n)], axis=1)
    with open(path, "w") as f:
        f.write("# width=346 height=260\n")
        np.savetxt(f, cols, fmt="%d")


def read_aedat(path: Path) -> tuple[np.ndarray, tuple[int, int]]:
    decoder = aedat.Decoder(str(path))
    streams = {i: s for i, s in decoder.id_to_stream().items() if s["type"] == "events"}
    if len(streams) != 1:
        fail(f"aedat: expected one event stream in {path}, found {decoder.id_to_stream()}")
    (stream_id, stream), = streams.items()
    parts = []
    for packet in decoder:
        if packet["stream_id"] == stream_id and "events" in packet:
            e = packet["events"]
            parts.append(np.stack([e["t"], e["x"], e["y"], e["on"]], axis=1).astype(np.int64))
    events = np.concatenate(parts) if parts else np.zeros((0, 4), dtype=np.int64)
    return events, (int(stream["width"]), int(stream["height"]))


def compare(name: str, got: np.ndarray, want: np.ndarray) -> None:
    if got.shape != want.shape:
        fail(f"{name}: {len(got)} events, evpipe's text output has {len(want)}")
    diff = np.nonzero(np.any(got != want, axis=1))[0]
    if len(diff):
        i = int(diff[0])
        fail(f"{name}: {len(diff)} events differ; first at index {i}: got (t x y p) {got[i].tolist()}, "
             f"expected {want[i].tolist()}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--evconvert", help="evconvert executable (default: $EVCONVERT or a build folder)")
    ap.add_argument("--build", help="build folder to take evconvert from (e.g. build/ci)")
    ap.add_argument("--input", type=Path, help="recording to convert (default: the E-MLB demo file)")
    ap.add_argument("--keep", type=Path, help="write the files here and keep them")
    args = ap.parse_args()

    evconvert = evpipe_pyenv.find_binary("evconvert", args.evconvert, "EVCONVERT", args.build)
    if evconvert is None:
        evpipe_pyenv.skip("evconvert not found (build the evconvert target or pass --evconvert)")

    print(f"evconvert: {evconvert}")
    with tempfile.TemporaryDirectory(prefix="evpipe-check-aedat4-") as tmp:
        work = args.keep or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        source = args.input or evpipe_pyenv.default_recording()
        if not source.exists():
            if args.input:
                fail(f"{source} does not exist")
            source = work / "synthetic.txt"
            synthetic_text(source)
        ref_path = work / "reference.txt"
        run([str(evconvert), "-q", str(source), str(ref_path)])
        ref, ref_size = read_text(ref_path)
        if len(ref) == 0:
            fail(f"{source} has no events")
        print(f"{source}: {len(ref)} events, {ref_size[0]}x{ref_size[1]}" if ref_size else f"{source}: {len(ref)} events")

        for compression in ("lz4", "zstd", "none"):
            out = work / f"evpipe-{compression}.aedat4"
            run([str(evconvert), "-q", "--compression", compression, str(source), str(out)])
            dv_events, dv_size, dv_range = evpipe_pyenv.read_with_dv(out)
            compare(f"dv-processing ({compression})", dv_events, ref)
            ae_events, ae_size = read_aedat(out)
            compare(f"aedat ({compression})", ae_events, ref)
            if ref_size and (dv_size != ref_size or ae_size != ref_size):
                fail(f"{compression}: resolution dv-processing {dv_size}, aedat {ae_size}, expected {ref_size}")
            # dv-processing's time range comes from the data table (end exclusive or inclusive by version)
            if dv_range[0] != ref[0, 0] or dv_range[1] not in (ref[-1, 0], ref[-1, 0] + 1):
                fail(f"{compression}: dv-processing time range {dv_range}, events span {ref[0, 0]}..{ref[-1, 0]}")
            print(f"  {compression:>4}: {out.stat().st_size} bytes; dv-processing and aedat read {len(ref)} "
                  f"identical events, {dv_size[0]}x{dv_size[1]}, time range {dv_range[0]}..{dv_range[1]}")
    print("OK")


if __name__ == "__main__":
    main()
