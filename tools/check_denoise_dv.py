#!/usr/bin/env python3
"""Compares evpipe's baf and knoise filters with dv-processing 2.0.4, decision by decision.

For each input, the events evpipe's reader delivers (`evdenoise_decisions --events`, file order) are fed one by one
to dv-processing's BackgroundActivityNoiseFilter (2 ms and 10 ms) and KNoiseFilter (1 ms) through `retain()`
(whose kept count is checked against `accept()` + `generateEvents()` on the whole store), and to evpipe's
`baf` / `baf duration_us=10000` / `knoise` through `evdenoise_decisions` (Filter interface, 10 000-event pushes).
Every per-event decision must be identical.

Inputs: the five recordings of denoise.md §8.4 under ../shared/data/real (each skipped when absent; for the AEDAT
4.0 files dv-processing's own reader must also deliver exactly the same events), and seeded uniform noise over
346x260 (NumPy default_rng(SEED), timestamps uniform in [1, T] µs, polarity 50/50) at 1 and 5 Hz/px.

Exit status: 0 identical, 1 on any difference or failure, 77 "skipped: <why>" when evdenoise_decisions (build the
`evdenoise_decisions` target of tests/bench) or the Python packages are not available.

  tools/check_denoise_dv.py [--build DIR | --tool PATH] [--seed N] [--noise-seconds T] [--keep DIR]
"""

from __future__ import annotations

import argparse
import datetime
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import evpipe_pyenv  # noqa: E402

evpipe_pyenv.ensure_packages(["dv_processing", "numpy"])

import dv_processing as dv  # noqa: E402
import numpy as np  # noqa: E402

REAL = evpipe_pyenv.REPO.parent / "shared" / "data" / "real"
FILES = [
    "davis346-faery/davis346.aedat4",
    "emlb-demo-01/demo-01.aedat4",
    "dvxplorer-tonic/sample.aedat4",
    "davis240c-rotdisk/IMU_rotDisk.aedat",
    "davis240c-translboxes/IMU_translBoxes.aedat",
]
# (label, evpipe filter + settings, dv-processing factory)
FILTERS = [
    ("BA 2 ms", ["--filter", "baf"],
     lambda res: dv.noise.BackgroundActivityNoiseFilter(res, datetime.timedelta(microseconds=2000))),
    ("BA 10 ms", ["--filter", "baf", "--set", "duration_us=10000"],
     lambda res: dv.noise.BackgroundActivityNoiseFilter(res, datetime.timedelta(microseconds=10000))),
    ("KNoise 1 ms", ["--filter", "knoise"],
     lambda res: dv.noise.KNoiseFilter(res, datetime.timedelta(microseconds=1000))),
]

failures: list[str] = []


def run(cmd: list[str]) -> bytes:
    r = subprocess.run(cmd, capture_output=True)
    if r.returncode != 0:
        print(f"FAIL: {' '.join(cmd)} exited with {r.returncode}: {r.stderr.decode(errors='replace').strip()}")
        sys.exit(1)
    return r.stdout


def evpipe_events(tool: Path, path: Path) -> tuple[np.ndarray, tuple[int, int]]:
    text = run([str(tool), "--events", str(path)]).decode()
    header, _, body = text.partition("\n")
    fields = dict(kv.split("=", 1) for kv in header[1:].split())
    cols = np.array(body.split(), dtype=np.int64).reshape(-1, 4)
    return cols, (int(fields["width"]), int(fields["height"]))


def dv_decisions(make, res: tuple[int, int], ev: np.ndarray) -> np.ndarray:
    f = make(res)
    keep = np.fromiter((f.retain(dv.Event(int(t), int(x), int(y), bool(p))) for t, x, y, p in ev), dtype=bool,
                       count=len(ev))
    # retain() is the per-event step of accept(): the whole-store path must keep the same number.
    store = dv.EventStore()
    for t, x, y, p in ev:
        store.push_back(int(t), int(x), int(y), bool(p))
    g = make(res)
    g.accept(store)
    n = g.generateEvents().size()
    if n != int(keep.sum()):
        failures.append(f"dv-processing retain() keeps {int(keep.sum())} but accept() keeps {n}")
    return keep


def compare(tool: Path, name: str, path: Path, ev: np.ndarray, res: tuple[int, int]) -> None:
    for label, args, make in FILTERS:
        want = dv_decisions(make, res, ev)
        out = run([str(tool), *args, str(path)])
        got = np.frombuffer(out, dtype=np.uint8)[::2] == ord("1")
        if got.shape != want.shape:
            failures.append(f"{name} {label}: evpipe gave {len(got)} decisions for {len(want)} events")
            print(f"  {label:<12} FAIL: {len(got)} decisions for {len(want)} events")
            continue
        diff = np.nonzero(got != want)[0]
        status = "identical" if len(diff) == 0 else f"{len(diff)} DIFFERENT"
        print(f"  {label:<12} kept {int(got.sum()):>8} (dv {int(want.sum()):>8})  {status}")
        if len(diff):
            i = int(diff[0])
            failures.append(f"{name} {label}: {len(diff)} decisions differ; first at event {i} (t x y p "
                            f"{ev[i].tolist()}): evpipe {int(got[i])}, dv-processing {int(want[i])}")


def noise(seed: int, rate_hz: float, seconds: float, res: tuple[int, int]) -> np.ndarray:
    rng = np.random.default_rng(seed)
    w, h = res
    n = int(round(rate_hz * w * h * seconds))
    t = np.sort(rng.integers(1, int(seconds * 1e6) + 1, n))
    return np.stack([t, rng.integers(0, w, n), rng.integers(0, h, n), rng.integers(0, 2, n)], axis=1)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--tool", help="evdenoise_decisions executable (default: $EVDENOISE_DECISIONS or a build folder)")
    ap.add_argument("--build", help="build folder to take evdenoise_decisions from")
    ap.add_argument("--seed", type=int, default=1, help="seed of the synthetic noise (default 1)")
    ap.add_argument("--noise-seconds", type=float, default=1.0, help="length of the synthetic noise (default 1 s)")
    ap.add_argument("--keep", type=Path, help="write the synthetic noise files here and keep them")
    args = ap.parse_args()

    tool = evpipe_pyenv.find_binary("evdenoise_decisions", args.tool, "EVDENOISE_DECISIONS", args.build)
    if tool is None:
        evpipe_pyenv.skip("evdenoise_decisions not found (build the evdenoise_decisions target or pass --tool)")
    print(f"evdenoise_decisions: {tool}")

    for rel in FILES:
        path = REAL / rel
        if not path.exists():
            print(f"{rel}: absent, skipped")
            continue
        ev, res = evpipe_events(tool, path)
        print(f"{rel}: {len(ev)} events, {res[0]}x{res[1]}")
        if path.suffix == ".aedat4":
            mine = evpipe_pyenv.read_with_dv(path)[0]
            if mine.shape != ev.shape or np.any(mine != ev):
                failures.append(f"{rel}: dv-processing's reader delivers other events than evpipe's")
                print("  FAIL: dv-processing's reader delivers other events than evpipe's")
                continue
        compare(tool, rel, path, ev, res)

    with tempfile.TemporaryDirectory(prefix="evpipe-check-denoise-") as tmp:
        work = args.keep or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        for rate in (1.0, 5.0):
            res = (346, 260)
            ev = noise(args.seed, rate, args.noise_seconds, res)
            path = work / f"noise-{rate:g}hz-seed{args.seed}.txt"
            with open(path, "w") as f:
                f.write(f"# width={res[0]} height={res[1]}\n")
                np.savetxt(f, ev, fmt="%d")
            name = f"noise {rate:g} Hz/px, {args.noise_seconds:g} s, seed {args.seed}"
            print(f"{name}: {len(ev)} events")
            compare(tool, name, path, ev, res)

    if failures:
        for f in failures:
            print(f"FAIL: {f}")
        sys.exit(1)
    print("OK: every decision identical")


if __name__ == "__main__":
    main()
