# SPDX-License-Identifier: Apache-2.0
"""Writes OUTDIR/report.html for scripts/main-job.sh: a self-contained page
(images embedded) with each spatial method's error on the analytic chart,
whole image and edge pixels, and crops magnified with nearest-neighbour."""
import base64
import html
import json
import pathlib
import sys


def embed(path):
    data = base64.b64encode(pathlib.Path(path).read_bytes()).decode()
    return f"data:image/png;base64,{data}"


def main():
    out = pathlib.Path(sys.argv[1])
    methods = sys.argv[2:]
    rows = []
    for m in methods:
        whole = json.loads((out / m / "all.json").read_text())["mean"]
        edges = json.loads((out / m / "edges.json").read_text())["mean"]
        rows.append((m, whole, edges))
    base = rows[0][1]["psnr"], rows[0][2]["psnr"]
    table = "".join(
        f"<tr><td>{html.escape(m)}</td><td>{w['psnr']:.2f}</td><td>{w['psnr'] - base[0]:+.2f}</td>"
        f"<td>{e['psnr']:.2f}</td><td>{e['psnr'] - base[1]:+.2f}</td><td>{w['ssim']:.4f}</td>"
        f"<td>{w['flip']:.4f}</td></tr>"
        for m, w, e in rows)
    images = "".join(
        f"<figure><img src='{embed(out / m / 'chart_1spp.png')}'><figcaption>{html.escape(m)}</figcaption></figure>"
        for m in methods)
    ref = embed(out / "scene" / "chart_reference.png")
    page = f"""<!doctype html><meta charset="utf-8"><title>Crisp: spatial methods on the analytic chart</title>
<style>body{{font-family:sans-serif;margin:2em}} table{{border-collapse:collapse}} td,th{{border:1px solid #ccc;padding:4px 8px;text-align:right}}
figure{{display:inline-block;margin:4px}} img{{width:960px;image-rendering:pixelated}}</style>
<h1>Spatial anti-aliasing on the analytic test chart</h1>
<p>1-sample image (pixel centres) filtered by each method, measured against the exact 16&times;16 box-filtered
reference on display-encoded values (sRGB of linear clamped to [0,1]). "Edge pixels" are the pixels cut by an edge.</p>
<table><tr><th>method</th><th>PSNR dB</th><th>&Delta; vs none</th><th>edge PSNR dB</th><th>&Delta; vs none</th><th>SSIM</th><th>perceptual error</th></tr>{table}</table>
<h2>Images (shown at 2&times;, nearest neighbour)</h2>
<figure><img src='{ref}'><figcaption>reference (16&times;16 box)</figcaption></figure>{images}
"""
    (out / "report.html").write_text(page)


if __name__ == "__main__":
    main()
