# SPDX-License-Identifier: Apache-2.0
"""Issue 4's figures from `crisp eval` output folders: per scene and method, the means over the frames
after a warm-up (PSNR, SSIM, perceptual error, temporal error), the distance to EEVEE at 8 samples,
the bars of issue 4, and on a scene with a moving object a ghosting error.

Ghosting error (seed 000's ghosting protocol, measured where ghosts live): the mean absolute error,
on display-encoded values, over the pixels whose reference changed by more than 0.1 in the previous
`--trail` frames: the background just uncovered by a moving object and the object's new position.
A method that keeps stale history there (a ghost trail) scores high.

Runs inside Blender (for its EXR reader, which reads the zip-compressed files crisp writes):
    blender -b --factory-startup --python tools/temporal_figures.py -- [--warmup 8] [--trail 8]
        [--split] [--plate-oracle] [--json OUT.json] EVALDIR...
Prints a Markdown table per scene."""

import argparse
import functools
import json
import math
import os
import sys

import bpy
import numpy as np

TEMPORAL = ("taa", "taa-improved", "phlm")


@functools.lru_cache(maxsize=64)  # the ghosting mask reads each reference frame `trail` times
def read_rgb(path):
    img = bpy.data.images.load(path, check_existing=False)
    w, h = img.size
    a = np.array(img.pixels[:], dtype=np.float32).reshape(h, w, 4)[..., :3]
    bpy.data.images.remove(img)
    return a


def encode(a):
    a = np.clip(a, 0.0, 1.0)
    return np.where(a <= 0.0031308, 12.92 * a, 1.055 * np.power(a, 1 / 2.4) - 0.055)


def reference_frame(ref_dir, f):
    """Frame f of the reference, display-encoded."""
    return encode(read_rgb(os.path.join(ref_dir, "frame_%04d.exr" % f)))


def method_frame(evaldir, files, f):
    """A method's frame f (files: frame -> path in evaldir), display-encoded."""
    return encode(read_rgb(os.path.join(evaldir, files[f])))


def mean_after(rows, key, warmup):
    vals = [r[key] for r in rows if r["frame"] > warmup and r.get(key) is not None]
    return sum(vals) / len(vals) if vals else float("nan")


def ghosting_error(evaldir, files, ref_dir, frames, warmup, trail):
    """Mean |out - ref| (display-encoded) over recently changed reference pixels, frames after warm-up."""
    total, count = 0.0, 0
    for i, f in enumerate(frames):
        if f <= warmup or i < trail:
            continue
        ref = reference_frame(ref_dir, f)
        changed = np.zeros(ref.shape[:2], dtype=bool)
        for k in range(1, trail + 1):
            prev = reference_frame(ref_dir, frames[i - k])
            changed |= np.abs(ref - prev).max(axis=2) > 0.1
        if not changed.any():
            continue
        out = method_frame(evaldir, files, f)
        err = np.abs(out - ref).mean(axis=2)
        total += float(err[changed].sum())
        count += int(changed.sum())
    return total / count if count else float("nan")


def temporal_split(evaldir, files, ref_dir, frames, warmup, trail):
    """--split: METHODS.md's temporal error with W = identity (so a moving object's own pixels count
    too), as the sum of two parts over all pixels: "quiet" pixels, whose reference changed by at most
    0.02 (display-encoded) in each of the last `trail` frames, and "recent" ones (the rest). Returns
    (total, quiet part, recent part, recent share of the pixels)."""
    quiet = recent = 0.0
    pixels = recent_pixels = 0
    for i, f in enumerate(frames):
        if f <= warmup or i < 1:
            continue
        ref = reference_frame(ref_dir, f)
        ref_prev = reference_frame(ref_dir, frames[i - 1])
        changed = np.zeros(ref.shape[:2], dtype=bool)
        for k in range(0, min(trail, i)):
            a = reference_frame(ref_dir, frames[i - k])
            b = reference_frame(ref_dir, frames[i - k - 1])
            changed |= np.abs(a - b).max(axis=2) > 0.02
        out = method_frame(evaldir, files, f)
        out_prev = method_frame(evaldir, files, frames[i - 1])
        te = np.abs((out - out_prev) - (ref - ref_prev)).mean(axis=2)
        quiet += float(te[~changed].sum())
        recent += float(te[changed].sum())
        pixels += te.size
        recent_pixels += int(changed.sum())
    if not pixels:
        return None
    return ((quiet + recent) / pixels, quiet / pixels, recent / pixels, recent_pixels / pixels)


def plate_oracle(evaldir, files, ref_dir, frames, warmup, settle=8):
    """--plate-oracle: an upper bound for a "background plate" (a second history that gives a revealed
    pixel back its settled value at once and holds it). The oracle knows the reference: a pixel is
    settled once its reference changed by at most 0.02 (display-encoded) in each of the last `settle`
    frames, and its plate is the method's output then. A pixel whose reference comes back within 0.02
    of its plate's reference before it has settled again shows the plate, and keeps showing it (its
    plate unchanged) until its reference leaves it again. Returns the temporal error with W =
    identity and the mean PSNR over frames after warm-up, of the method as it is and with the plate."""
    ref = np.stack([reference_frame(ref_dir, f) for f in frames])
    out = np.stack([method_frame(evaldir, files, f) for f in frames])
    plated = out.copy()
    settled_for = np.zeros(ref.shape[1:3], dtype=int)
    showing = np.zeros(ref.shape[1:3], dtype=bool)
    plate = np.full(ref.shape[1:], np.nan, dtype=np.float32)
    plate_ref = np.full(ref.shape[1:], np.nan, dtype=np.float32)
    for t in range(len(frames)):
        if t > 0:
            settled_for = np.where(np.abs(ref[t] - ref[t - 1]).max(axis=2) <= 0.02, settled_for + 1, 0)
        settled = settled_for >= settle
        at_plate = np.isfinite(plate_ref[..., 0]) & (np.abs(ref[t] - plate_ref).max(axis=2) <= 0.02)
        showing = at_plate & (showing | ~settled)
        plated[t][showing] = plate[showing]
        learn = settled & ~showing
        plate[learn] = out[t][learn]
        plate_ref[learn] = ref[t][learn]
    after = [t for t, f in enumerate(frames) if f > warmup and t > 0]

    def figures(a):
        te = np.mean([np.abs((a[t] - a[t - 1]) - (ref[t] - ref[t - 1])).mean() for t in after])
        psnr = np.mean([-10 * np.log10(max(float(np.mean((a[t] - ref[t]) ** 2)), 1e-12)) for t in after])
        return float(te), float(psnr)
    return figures(out) + figures(plated)


def summarize(evaldir, warmup, trail, split=False, oracle=False):
    with open(os.path.join(evaldir, "results.json")) as fh:
        results = json.load(fh)
    out = []
    for scene in results["scenes"]:
        ref_dir = os.path.join(evaldir, "renders", "reference_%d" % scene["reference"]["samples"]) \
            if isinstance(scene.get("reference"), dict) and "samples" in scene["reference"] else None
        if ref_dir is None or not os.path.isdir(ref_dir):
            ref_dir = next(os.path.join(evaldir, "renders", d) for d in sorted(os.listdir(os.path.join(evaldir, "renders")))
                           if d.startswith("reference_"))
        moving = "nothing moves" not in str(scene.get("temporal_error_warp", ""))
        rows = []
        for m in scene["methods"] + scene["eevee_curve"]:
            frames = [r["frame"] for r in m["frames"]]
            files = {r["frame"]: r["file"] for r in m["frames"]}
            row = {"name": m["name"], "kind": m["kind"], "samples": m.get("samples", 1)}
            for key in ("psnr", "ssim", "perceptual_error", "temporal_error", "filter_s", "time_s"):
                row[key] = mean_after(m["frames"], key, warmup)
            row["ghosting_error"] = ghosting_error(evaldir, files, ref_dir, frames, warmup, trail) if moving else None
            if split and moving:
                row["temporal_split"] = temporal_split(evaldir, files, ref_dir, frames, warmup, trail)
            if oracle and moving and m["name"] in ("none", "blender-smaa") + TEMPORAL:
                row["plate_oracle"] = plate_oracle(evaldir, files, ref_dir, frames, warmup)
            rows.append(row)
        out.append({"scene": scene["name"], "resolution": scene["resolution"], "frames": scene["frames"],
                    "reference": os.path.basename(ref_dir), "warmup": warmup, "trail": trail, "rows": rows,
                    "bars": bars(rows)})
    return out


def bars(rows):
    by = {r["name"]: r for r in rows}
    res = {}
    for m in TEMPORAL:
        if m not in by:
            continue
        r = by[m]
        for base in ("none", "blender-smaa"):
            if base in by:
                res["%s beats %s on PSNR" % (m, base)] = r["psnr"] > by[base]["psnr"]
                res["%s beats %s on temporal error" % (m, base)] = r["temporal_error"] < by[base]["temporal_error"]
    if "taa" in by and "taa-improved" in by and by["taa"]["ghosting_error"] is not None:
        res["taa-improved less ghosting than taa"] = by["taa-improved"]["ghosting_error"] < by["taa"]["ghosting_error"]
    if "taa" in by and "phlm" in by:
        res["phlm >= taa on PSNR"] = by["phlm"]["psnr"] >= by["taa"]["psnr"]
        res["phlm <= taa on temporal error"] = by["phlm"]["temporal_error"] <= by["taa"]["temporal_error"]
    return res


def fmt(v, spec):
    return "-" if v is None or (isinstance(v, float) and math.isnan(v)) else format(v, spec)


def markdown(summary):
    lines = []
    for s in summary:
        lines.append("### %s (%s, frames %s, %s; means over frames > %d)" % (
            s["scene"], "x".join(map(str, s["resolution"])), "-".join(map(str, s["frames"])), s["reference"], s["warmup"]))
        lines.append("")
        eevee8 = next((r for r in s["rows"] if r["name"] == "eevee-8"), None)
        lines.append("| method | PSNR | SSIM | perceptual | temporal err | ghosting err | dB to EEVEE 8 | filter ms |")
        lines.append("|---|---|---|---|---|---|---|---|")
        for r in s["rows"]:
            gap = (r["psnr"] - eevee8["psnr"]) if eevee8 else None
            lines.append("| %s | %s | %s | %s | %s | %s | %s | %s |" % (
                r["name"], fmt(r["psnr"], ".2f"), fmt(r["ssim"], ".4f"), fmt(r["perceptual_error"], ".4f"),
                fmt(r["temporal_error"], ".4f"), fmt(r["ghosting_error"], ".4f"), fmt(gap, "+.2f"),
                fmt(r["filter_s"] * 1000 if r["filter_s"] == r["filter_s"] else None, ".1f")))
        lines.append("")
        for k, v in s["bars"].items():
            lines.append("- %s: %s" % (k, "yes" if v else "**NO**"))
        lines.append("")
        split = [r for r in s["rows"] if r.get("temporal_split")]
        if split:
            share = split[0]["temporal_split"][3]
            lines.append("Temporal error with W = identity, split (`--split`; recent: %.0f %% of the pixels):" % (100 * share))
            lines.append("")
            lines.append("| method | total | quiet part | recent part |")
            lines.append("|---|---|---|---|")
            for r in split:
                t = r["temporal_split"]
                lines.append("| %s | %.5f | %.5f | %.5f |" % (r["name"], t[0], t[1], t[2]))
            lines.append("")
        oracle = [r for r in s["rows"] if r.get("plate_oracle")]
        if oracle:
            lines.append("Oracle background plate (`--plate-oracle`; W = identity): temporal error and PSNR as they are "
                         "-> with the plate:")
            lines.append("")
            lines.append("| method | temporal err | with plate | PSNR | with plate |")
            lines.append("|---|---|---|---|---|")
            for r in oracle:
                t = r["plate_oracle"]
                lines.append("| %s | %.5f | %.5f | %.2f | %.2f |" % (r["name"], t[0], t[2], t[1], t[3]))
            lines.append("")
    return "\n".join(lines)


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser(prog="temporal_figures.py")
    p.add_argument("evaldirs", nargs="+")
    p.add_argument("--warmup", type=int, default=8, help="frames left out of the means (default 8)")
    p.add_argument("--trail", type=int, default=8, help="frames of reference change the ghosting mask covers")
    p.add_argument("--json", default="")
    p.add_argument("--split", action="store_true",
                   help="also split the temporal error (identity warp) into quiet and recently changed pixels")
    p.add_argument("--plate-oracle", action="store_true",
                   help="also bound a background plate: the temporal error (identity warp) and PSNR with an oracle "
                        "that shows a revealed pixel's settled output at once")
    a = p.parse_args(argv)
    summary = []
    for d in a.evaldirs:
        summary += summarize(d, a.warmup, a.trail, a.split, a.plate_oracle)
    print(markdown(summary))
    if a.json:
        with open(a.json + ".tmp", "w") as fh:
            json.dump(summary, fh, indent=1)
        os.replace(a.json + ".tmp", a.json)


main()
