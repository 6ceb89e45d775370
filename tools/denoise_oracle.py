#!/usr/bin/env python3
"""Oracle bound for denoising evsim's 2D scenes: the best a decision from the significance filter's neighbourhood
could reach if it knew the true local edge motion (issue 18: "what the best possible decision from the same
neighbourhood could reach").

For every event e = (p, t, polarity) the oracle knows the scene's edge through p's neighbourhood: the unit normal n
of the nearest edge of the evsim shape at t and its normal speed v_n (translating-rect: the rectangle's velocity,
rotating-bar: the rotation's velocity at p). If e lies on that edge, the pixel p + q (q in the 5x5 block, q != 0) is
crossed at t + tau_q, tau_q = (q . n) / v_n, with e's polarity. A *slot* is such a predicted event inside the
filter's own neighbourhood in time, -T <= tau_q <= L (T = 1 / slowest_speed_px_s = 0.5 s, L = the look-ahead,
20 ms); it is *filled* when the recording holds an event of e's polarity at p + q within the filter's own tolerance
|t_j - (t + tau_q)| <= delta0 + eps |tau_q| (2 ms, 0.1 px). Under background activity at the true rate lambda a
slot is filled by chance with probability pi_q = 1 - exp(-(lambda / 2) * window_q), independently, so the number
of filled slots K has a Poisson-binomial null; the oracle's score is -log10 P(K >= k_observed). It uses every
event (no 4-event ring), knows lambda and needs no search over directions or speeds (no multiple-comparison cost):
a filter that does not know the motion cannot do better at the same false-alarm rate from the same events.

Printed per recording: SR / NR / F1 of the oracle at the filter's false-alarm budget (P <= alpha = 5e-4), the best F1
over every threshold of its score (the bound), and, with --evdenoise, the significance filter's own figures, also
over the target's edges alone (edges at >= 3 px/s, and those once they have the 2 pixels of history a 5x5 test
needs: `subsets`).

  tools/denoise_oracle.py SCENE.txt --scene translating-rect --speed 0.025 --noise-hz 5 [--evdenoise BIN]
  tools/denoise_oracle.py --make-slow [--build build/release] [--work build/oracle] [--seeds 1,7] [--json FILE]

--make-slow makes the slow-edge scenes of docs/results-denoise.md (e) with evsim (seed 1 and the given seeds)
and prints one markdown table (tools/denoise_results.py includes it).
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import evpipe_pyenv  # noqa: E402

evpipe_pyenv.ensure_packages(["numpy"])

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
T_S = 0.5  # the filter's window T = 1 / slowest_speed_px_s
L_S = 0.02  # the filter's look-ahead
DELTA0_S = 0.002  # timing_jitter_us
EPS = 0.1  # edge_precision_px
ALPHA = 5e-4
SLOW_SCENES = [("translating-rect", 0.025), ("translating-rect", 0.0625), ("translating-rect", 0.125),
               ("rotating-bar", 0.05)]
SLOW_RATES = [0.1, 1, 3, 5]
# The slow-edge targets are about edges at 3-15 px/s: an edge fires by moving across itself, so its speed is
# its normal speed. translating-rect turns its rectangle by 0.2 rad and moves it along x: its two sides across the
# motion move at v cos 0.2 (2.94 px/s at x0.025), the two along it at v sin 0.2 (0.6 / 1.5 / 2.98 px/s); the
# rotating bar's edges slow down towards its centre. "In range" = normal speed >= 3 px/s less the 2 % the turn
# takes off the moving sides (3 cos 0.2 = 2.94).
TARGET_MIN_SPEED_PX_S = 2.9


def load(path: Path):
    a = np.loadtxt(path, dtype=np.int64, comments="#", ndmin=2)
    width, height = 346, 260
    with open(path) as f:
        head = f.readline()
    if head.startswith("#") and "width=" in head:
        parts = dict(kv.split("=") for kv in head[1:].split())
        width, height = int(parts["width"]), int(parts["height"])
    return a[:, 0], a[:, 1], a[:, 2], a[:, 3], a[:, 4], width, height


def shape(scene: str, speed: float, width: int, height: int):
    """(half-width, half-height, centre(t), angle(t), velocity(x, y, t)) of evsim's shape (libs/sim/scene2d.cpp)."""
    if scene == "translating-rect":
        vx = 120.0 * speed
        return (20.0, 15.0, lambda t: (30.0 + vx * t, 0.25 * height + 0 * t), lambda t: 0.2 + 0 * t,
                lambda x, y, t: (vx + 0 * x, 0 * x))
    if scene == "rotating-bar":
        w = math.pi * speed
        cx, cy = width / 2.0, height / 2.0
        return (0.3 * height, 3.0, lambda t: (cx + 0 * t, cy + 0 * t), lambda t: w * t,
                lambda x, y, t: (-w * (y - cy), w * (x - cx)))
    raise SystemExit(f"denoise_oracle.py: unknown scene {scene}")


def edge_normals(scene, speed, x, y, t_s, width, height):
    """Unit normal (along the motion) and normal speed of the shape's edge nearest to each point."""
    hw, hh, centre, angle, velocity = shape(scene, speed, width, height)
    cx, cy = centre(t_s)
    a = angle(t_s)
    c, s = np.cos(a), np.sin(a)
    px, py = x + 0.5, y + 0.5  # evsim samples pixel centres
    dx, dy = px - cx, py - cy
    lx, ly = c * dx + s * dy, -s * dx + c * dy  # shape frame
    # Distance to each of the 4 edges (segments); local outward normals (+-1, 0), (0, +-1).
    d_right = np.hypot(np.abs(lx - hw), np.maximum(np.abs(ly) - hh, 0))
    d_left = np.hypot(np.abs(lx + hw), np.maximum(np.abs(ly) - hh, 0))
    d_bottom = np.hypot(np.abs(ly - hh), np.maximum(np.abs(lx) - hw, 0))
    d_top = np.hypot(np.abs(ly + hh), np.maximum(np.abs(lx) - hw, 0))
    k = np.argmin(np.stack([d_right, d_left, d_bottom, d_top]), axis=0)
    nlx = np.choose(k, [1.0, -1.0, 0.0, 0.0])
    nly = np.choose(k, [0.0, 0.0, 1.0, -1.0])
    nx, ny = c * nlx - s * nly, s * nlx + c * nly  # back to the image frame
    vx, vy = velocity(px, py, t_s)
    vn = vx * nx + vy * ny
    flip = vn < 0  # normal along the motion
    nx, ny, vn = np.where(flip, -nx, nx), np.where(flip, -ny, ny), np.abs(vn)
    return nx, ny, vn


def oracle_scores(rec, scene: str, speed: float, rate_hz: float):
    """The oracle's p-value per event of a loaded recording (load()), its labels and each event's normal speed."""
    t, x, y, p, label, width, height = rec
    t0 = t.min()
    tr = (t - t0).astype(np.int64)
    t_s = tr * 1e-6
    nx, ny, vn = edge_normals(scene, speed, x, y, t_s, width, height)
    pix = (y * width + x).astype(np.int64)
    key = ((pix * 2 + p) << 32) + tr
    order = np.sort(key)
    n = len(t)
    # Poisson-binomial distribution of the filled-slot count under noise, per event: dp[:, k] = P(K = k).
    dp = np.zeros((n, 25))
    dp[:, 0] = 1.0
    filled = np.zeros(n, dtype=np.int64)
    for qx in range(-2, 3):
        for qy in range(-2, 3):
            if qx == 0 and qy == 0:
                continue
            with np.errstate(divide="ignore", invalid="ignore"):
                tau = np.where(vn > 1e-9, (qx * nx + qy * ny) / vn, np.inf)
            xs, ys = x + qx, y + qy
            ok = (tau >= -T_S) & (tau <= L_S) & (xs >= 0) & (xs < width) & (ys >= 0) & (ys < height)
            tol = DELTA0_S + EPS * np.abs(np.where(ok, tau, 0.0))
            lo = np.maximum(np.where(ok, tau, 0.0) - tol, -T_S)
            hi = np.minimum(np.where(ok, tau, 0.0) + tol, L_S)
            width_s = np.where(ok, hi - lo, 0.0)
            pi = 1.0 - np.exp(-(rate_hz / 2.0) * width_s)
            qpix = (np.clip(ys, 0, height - 1) * width + np.clip(xs, 0, width - 1)).astype(np.int64)
            base = (qpix * 2 + p) << 32
            klo = base + np.maximum(tr + np.floor(lo * 1e6).astype(np.int64), 0)
            khi = base + np.maximum(tr + np.ceil(hi * 1e6).astype(np.int64), 0)
            hit = ok & ((np.searchsorted(order, khi, side="right") - np.searchsorted(order, klo, side="left")) > 0)
            filled += hit
            dp[:, 1:] = dp[:, 1:] * (1.0 - pi[:, None]) + dp[:, :-1] * pi[:, None]
            dp[:, 0] *= 1.0 - pi
    tail = np.cumsum(dp[:, ::-1], axis=1)[:, ::-1]  # tail[:, k] = P(K >= k)
    pval = tail[np.arange(n), filled]
    pval = np.where(filled == 0, 1.0, pval)
    return pval, label, vn


def figures(keep, label):
    tp = int(np.sum(keep & (label == 1)))
    fp = int(np.sum(keep & (label == 0)))
    fn = int(np.sum(~keep & (label == 1)))
    tn = int(np.sum(~keep & (label == 0)))
    sr = tp / max(1, tp + fn)
    nr = tn / (tn + fp) if tn + fp > 0 else None
    f1 = 2 * tp / max(1, 2 * tp + fp + fn)
    return sr, nr, f1


def best_f1(pval, label):
    """Largest F1 over every threshold on the p-value (keep when p <= threshold)."""
    order = np.argsort(pval, kind="stable")
    pv, lab = pval[order], label[order]
    tp = np.cumsum(lab == 1)
    fp = np.cumsum(lab == 0)
    signal = int(np.sum(label == 1))
    last = np.r_[pv[1:] != pv[:-1], True]  # only cut between distinct p-values
    f1 = 2 * tp / (signal + tp + fp)
    f1 = np.where(last & (pv < 1.0), f1, 0.0)
    i = int(np.argmax(f1))
    keep = pval <= pv[i]
    sr, nr, f = figures(keep, label)
    return f, sr, nr, float(pv[i])


def subsets(t, vn, label):
    """Masks of the events scored on the target's edges: every noise event plus the signal events on edges in the
    target's speed range ("in range"), and of those only the ones whose edge has crossed the 2 pixels behind it
    since the scene started (t >= 2 / v_n, "settled": the history any line or surface in the 5x5 block needs)."""
    t_s = (t - t.min()) * 1e-6
    noise = label == 0
    in_range = noise | (vn >= TARGET_MIN_SPEED_PX_S)
    with np.errstate(divide="ignore"):
        settled = in_range & (noise | (t_s >= np.where(vn > 0, 2.0 / vn, np.inf)))
    return in_range, settled


def filter_keep(path: Path, rec, evdenoise: str):
    """significance's decisions per event of the recording (rec: its load()), and its metrics."""
    out = path.with_suffix(".oracle-out.txt")
    r = subprocess.run([evdenoise, str(path), str(out), "--filter", "significance", "--metrics"],
                       capture_output=True, text=True, check=True)
    t, x, y, p = rec[:4]
    kept = np.loadtxt(out, dtype=np.int64, comments="#", ndmin=2)
    out.unlink(missing_ok=True)
    key = lambda a, b, c, d: ((a * 4096 + b) * 4096 + c) * 2 + d  # noqa: E731 (t, x, y, polarity)
    keep = np.isin(key(t, x, y, p), key(kept[:, 0], kept[:, 1], kept[:, 2], kept[:, 3])) if kept.size else \
        np.zeros(len(t), dtype=bool)
    return keep, json.loads(r.stdout)


def evaluate(path: Path, scene: str, speed: float, rate: float, evdenoise: str | None):
    """(oracle at alpha, oracle best, filter) over every event, then the filter's and the oracle's best F1 over the
    in-range and the settled subsets (None without evdenoise)."""
    rec = load(path)
    pval, label, vn = oracle_scores(rec, scene, speed, rate)
    at_alpha = figures(pval <= ALPHA, label)
    best = best_f1(pval, label)
    filt = None
    split = None
    if evdenoise:
        keep, m = filter_keep(path, rec, evdenoise)
        filt = (m["sr"], m["nr"], m["f1"])
        split = {}
        for name, mask in zip(("in_range", "settled"), subsets(rec[0], vn, label)):
            split[name] = {"signal": int(np.sum(label[mask] == 1)), "significance": figures(keep[mask], label[mask]),
                           "oracle_best": best_f1(pval[mask], label[mask])}
    return at_alpha, best, filt, split


def fmt(v):
    return "n/a" if v is None else f"{v:.3f}"


def make_slow(args) -> None:
    build = Path(args.build)
    evsim = build / "apps" / "evsim" / "evsim"
    evdenoise = build / "apps" / "evdenoise" / "evdenoise"
    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    seeds = [int(s) for s in args.seeds.split(",")]
    rows = []
    for scene, speed in SLOW_SCENES:
        for rate in SLOW_RATES:
            cells = []
            for seed in seeds:
                rec = work / f"{scene}-s{speed}-n{rate}-seed{seed}.txt"
                if not rec.exists():
                    tmp = rec.with_suffix(".aedat4")
                    subprocess.run([str(evsim), "--scene", scene, "--speed", str(speed), "--duration-ms", "1000",
                                    "--noise-hz", str(rate), "--hot-pixels", "0", "--seed", str(seed), "--out",
                                    str(tmp), "--labels", str(rec), "--no-manifest"], check=True,
                                   stdout=subprocess.DEVNULL)
                    tmp.unlink(missing_ok=True)
                cells.append(evaluate(rec, scene, speed, rate, str(evdenoise)))
            rows.append((scene, speed, rate, cells))
    if args.json:
        Path(args.json).write_text(json.dumps([
            {"scene": sc, "speed": sp, "rate": r, "seed": seed, "significance": list(filt), "oracle_at_alpha": list(aa),
             "oracle_best": list(best),
             "split": {k: {"signal": v["signal"], "significance": list(v["significance"]),
                           "oracle_best": list(v["oracle_best"])} for k, v in split.items()}}
            for sc, sp, r, cells in rows for seed, (aa, best, filt, split) in zip(seeds, cells)]))
    print("| scene | Hz/px | " + " | ".join(f"seed {s}: significance F1 (SR / NR) · oracle at α · oracle best F1 (SR / NR)"
                                               for s in seeds) + " |")
    print("|---|---:|" + "---|" * len(seeds))
    for scene, speed, rate, cells in rows:
        out = []
        for at_alpha, best, filt, _ in cells:
            out.append(f"{fmt(filt[2])} ({fmt(filt[0])} / {fmt(filt[1])}) · {fmt(at_alpha[2])} "
                       f"({fmt(at_alpha[0])} / {fmt(at_alpha[1])}) · **{fmt(best[0])}** ({fmt(best[1])} / {fmt(best[2])})")
        print(f"| {scene} ×{speed} | {rate} | " + " | ".join(out) + " |")
    # The same on the target's edges (see TARGET_MIN_SPEED_PX_S and subsets()), seed of the first column.
    print()
    print(f"On the target's edges, seed {seeds[0]}: signal events on edges with normal speed ≥ {TARGET_MIN_SPEED_PX_S} "
          "px/s and every noise event (*in range*), and of those signal events only the ones whose edge has crossed "
          "the two pixels behind it since the scene started, t ≥ 2 / v_n (*settled*). Cells: significance F1 (SR) · "
          "oracle best F1; n = the subset's signal events.")
    print()
    print("| scene | Hz/px | in range: n · significance · oracle | settled: n · significance · oracle |")
    print("|---|---:|---|---|")
    for scene, speed, rate, cells in rows:
        split = cells[0][3]
        out = [f"{split[k]['signal']} · {fmt(split[k]['significance'][2])} ({fmt(split[k]['significance'][0])}) · "
               f"{fmt(split[k]['oracle_best'][0])}" for k in ("in_range", "settled")]
        print(f"| {scene} ×{speed} | {rate} | " + " | ".join(out) + " |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("recording", nargs="?")
    ap.add_argument("--scene")
    ap.add_argument("--speed", type=float)
    ap.add_argument("--noise-hz", type=float)
    ap.add_argument("--evdenoise")
    ap.add_argument("--make-slow", action="store_true")
    ap.add_argument("--build", default=str(ROOT / "build" / "release"))
    ap.add_argument("--work", default=str(ROOT / "build" / "oracle"))
    ap.add_argument("--seeds", default="1")
    ap.add_argument("--json", help="with --make-slow: also write every cell here")
    a = ap.parse_args()
    if a.make_slow:
        make_slow(a)
        return
    if not (a.recording and a.scene and a.speed is not None and a.noise_hz is not None):
        ap.error("RECORDING, --scene, --speed and --noise-hz are needed (or --make-slow)")
    at_alpha, best, filt, split = evaluate(Path(a.recording), a.scene, a.speed, a.noise_hz, a.evdenoise)
    print(json.dumps({"oracle_at_alpha": {"sr": at_alpha[0], "nr": at_alpha[1], "f1": at_alpha[2]},
                      "oracle_best": {"f1": best[0], "sr": best[1], "nr": best[2], "p_threshold": best[3]},
                      "significance": None if filt is None else {"sr": filt[0], "nr": filt[1], "f1": filt[2]},
                      "split": split}))


if __name__ == "__main__":
    main()
