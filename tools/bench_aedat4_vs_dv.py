#!/usr/bin/env python3
"""AEDAT 4.0 decode throughput: evpipe vs dv-processing, on the same files, in one run.

Files: the E-MLB demo recording (../shared/data/real/emlb-demo-01/demo-01.aedat4, 319 512 events, LZ4) when
present, and a larger synthetic recording (default 4 M events) written by evpipe's writer through
`evconvert` (or by dv-processing's MonoCameraWriter when evconvert is not built).

dv-processing: MonoCameraRecording + getNextEventBatch() until None, best of N runs.
evpipe: the `bench_io` Google Benchmark with EVPIPE_BENCH_FILE=<file> (BM_DecodeFile, open + read every
batch), best of N repetitions. Build it in Release for meaningful numbers:
  cmake -S . -B build-rel -G Ninja -DCMAKE_BUILD_TYPE=Release && cmake --build build-rel --target bench_io evconvert

Prints Mev/s of both and the ratio evpipe/dv. Exit 0, 1 on failure, 77 "skipped: <why>" when bench_io or the
Python packages are not available.

  tools/bench_aedat4_vs_dv.py [--build DIR | --bench-io PATH] [--evconvert PATH] [--runs N] [--synthetic-events N] [FILE...]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import evpipe_pyenv  # noqa: E402

evpipe_pyenv.ensure_packages(["dv_processing", "numpy"])

import dv_processing as dv  # noqa: E402
import numpy as np  # noqa: E402


def dv_decode(path: Path) -> int:
    rec = dv.io.MonoCameraRecording(str(path))
    n = 0
    while True:
        batch = rec.getNextEventBatch()
        if batch is None:
            return n
        n += batch.size()


def dv_best(path: Path, runs: int) -> tuple[int, float]:
    """(events, best Mev/s) over `runs` full decodes."""
    best = float("inf")
    events = 0
    for _ in range(runs):
        t0 = time.perf_counter()
        events = dv_decode(path)
        best = min(best, time.perf_counter() - t0)
    return events, events / best / 1e6


def evpipe_best(bench_io: Path, path: Path, runs: int) -> tuple[int, float]:
    env = dict(os.environ, EVPIPE_BENCH_FILE=str(path))
    cmd = [str(bench_io), "--benchmark_filter=^BM_DecodeFile", "--benchmark_format=json",
           f"--benchmark_repetitions={runs}", "--benchmark_min_time=0.3"]
    r = subprocess.run(cmd, env=env, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} exited with {r.returncode}: {r.stderr.strip()}")
    report = json.loads(r.stdout)
    runs_json = [b for b in report["benchmarks"] if b.get("run_type", "iteration") == "iteration"]
    if not runs_json:
        raise RuntimeError(f"bench_io reported nothing for {path}")
    for b in runs_json:
        if b.get("error_occurred"):
            raise RuntimeError(f"bench_io: {b.get('error_message')}")
    return int(runs_json[0]["events"]), max(b["items_per_second"] for b in runs_json) / 1e6


def make_synthetic(work: Path, n: int, evconvert: Path | None) -> Path:
    """A time-ordered random 346x260 recording of n events, written as LZ4 AEDAT 4.0."""
    rng = np.random.default_rng(11)
    t = 1_600_000_000_000_000 + np.cumsum(rng.integers(0, 20, n))
    x = rng.integers(0, 346, n)
    y = rng.integers(0, 260, n)
    p = rng.integers(0, 2, n)
    out = work / f"synthetic-{n}.aedat4"
    if evconvert is not None:
        text = work / "synthetic.txt"
        with open(text, "w") as f:
            f.write("# width=346 height=260\n")
            np.savetxt(f, np.stack([t, x, y, p], axis=1), fmt="%d")
        r = subprocess.run([str(evconvert), "-q", str(text), str(out)], capture_output=True, text=True)
        text.unlink()
        if r.returncode != 0:
            raise RuntimeError(f"evconvert failed: {r.stderr.strip()}")
        return out
    store = dv.EventStore()
    for i in range(n):
        store.push_back(int(t[i]), int(x[i]), int(y[i]), bool(p[i]))
    config = dv.io.MonoCameraWriter.EventOnlyConfig("DAVIS346_SYNTH", (346, 260), compression=dv.CompressionType.LZ4)
    writer = dv.io.MonoCameraWriter(str(out), config)
    writer.writeEvents(store)
    del writer
    return out


def build_type(binary: Path) -> str:
    for d in binary.parents:
        cache = d / "CMakeCache.txt"
        if cache.exists():
            for line in cache.read_text(errors="replace").splitlines():
                if line.startswith("CMAKE_BUILD_TYPE:"):
                    return line.split("=", 1)[1] or "unset"
    return "unknown"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("files", nargs="*", type=Path, help="AEDAT 4.0 files (default: the demo + a synthetic one)")
    ap.add_argument("--build", help="build folder to take bench_io and evconvert from (e.g. build-rel)")
    ap.add_argument("--bench-io", help="bench_io executable (default: $EVPIPE_BENCH_IO or a build folder)")
    ap.add_argument("--evconvert", help="evconvert executable, to write the synthetic file")
    ap.add_argument("--runs", type=int, default=5, help="best of N runs (default 5)")
    ap.add_argument("--synthetic-events", type=int, default=4_000_000, help="0 = no synthetic file")
    args = ap.parse_args()

    bench_io = evpipe_pyenv.find_binary("bench_io", args.bench_io, "EVPIPE_BENCH_IO", args.build)
    if bench_io is None:
        evpipe_pyenv.skip("bench_io not found (build the bench_io target, Release, or pass --bench-io)")
    kind = build_type(bench_io)
    print(f"bench_io: {bench_io} (CMAKE_BUILD_TYPE={kind})")
    if kind not in ("Release", "RelWithDebInfo"):
        print("warning: bench_io is not a Release build; evpipe's numbers will be low", file=sys.stderr)
    print(f"dv-processing {dv.__version__ if hasattr(dv, '__version__') else '?'}, best of {args.runs} runs")

    with tempfile.TemporaryDirectory(prefix="evpipe-bench-aedat4-") as tmp:
        files: list[Path] = list(args.files)
        if not files:
            demo = evpipe_pyenv.default_recording()
            if demo.exists():
                files.append(demo)
            if args.synthetic_events > 0:
                evconvert = evpipe_pyenv.find_binary("evconvert", args.evconvert, "EVCONVERT", args.build)
                files.append(make_synthetic(Path(tmp), args.synthetic_events, evconvert))
                print(f"synthetic file written by {'evpipe (' + str(evconvert) + ')' if evconvert else 'dv-processing'}")
        if not files:
            evpipe_pyenv.skip("no input file")

        print(f"{'file':<34} {'events':>10} {'dv Mev/s':>10} {'evpipe Mev/s':>13} {'evpipe/dv':>10}")
        for path in files:
            try:
                n_dv, dv_rate = dv_best(path, args.runs)
                n_ev, ev_rate = evpipe_best(bench_io, path, args.runs)
            except Exception as e:  # noqa: BLE001 - report any failure of either decoder
                print(f"FAIL: {path}: {e}")
                sys.exit(1)
            note = "" if n_dv == n_ev else f"  (event counts differ: dv {n_dv}, evpipe {n_ev})"
            print(f"{path.name:<34} {n_ev:>10} {dv_rate:>10.1f} {ev_rate:>13.1f} {ev_rate / dv_rate:>10.2f}{note}")
            if note:
                sys.exit(1)


if __name__ == "__main__":
    main()
