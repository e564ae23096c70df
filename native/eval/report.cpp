// SPDX-License-Identifier: Apache-2.0
// OUTDIR/report.html: one self-contained page (no network; images by relative
// path under OUTDIR/images) built in the browser from the results JSON embedded
// in it. Charts are inline SVG. A self-check at load writes "OK" or the list of
// problems (broken images, missing charts) into the page title and console.
#include <string>

#include "cli/commands.h"
#include "eval/eval.h"

namespace crisp::eval {

namespace {

const char* kHead = R"HTML(<!doctype html>
<html lang="en"><head><meta charset="utf-8">
<title>crisp eval report</title>
<style>
body{font-family:system-ui,-apple-system,"Segoe UI",sans-serif;margin:24px auto;max-width:1500px;padding:0 16px;color:#222;background:#fafafa}
h1{margin-bottom:4px} h2{margin-top:36px;border-bottom:1px solid #ddd;padding-bottom:4px} .sub{color:#666;margin-top:0}
table{border-collapse:collapse;margin:8px 0;font-size:14px;background:#fff} td,th{border:1px solid #ccc;padding:4px 8px;text-align:right}
th{background:#f0f0f0} td.l,th.l{text-align:left} tr.best td{font-weight:600} tr.fail td{color:#b00}
.charts{display:flex;flex-wrap:wrap;gap:16px} .chart{background:#fff;border:1px solid #ddd;padding:8px}
.chart svg text{font-size:11px;fill:#333} .chart .t{font-size:13px;font-weight:600}
.crop{display:flex;flex-wrap:wrap;gap:8px;margin:8px 0 20px} figure{margin:0;text-align:center;font-size:12px}
img.px{image-rendering:pixelated;image-rendering:crisp-edges;border:1px solid #bbb;background:#000}
.grid{display:grid;grid-template-columns:repeat(auto-fill,minmax(250px,1fr));gap:10px}
.grid figure img{width:100%;height:auto}
.err{color:#b00;font-weight:600} code,pre{background:#eee;padding:2px 4px;font-size:12px} pre{padding:8px;overflow-x:auto;white-space:pre-wrap}
.controls{margin:8px 0;font-size:14px} .legend span{display:inline-block;margin-right:14px;font-size:13px}
.legend i{display:inline-block;width:12px;height:12px;margin-right:4px;vertical-align:-1px;border-radius:2px}
details{margin:8px 0} summary{cursor:pointer;font-weight:600}
</style></head><body>
<noscript><p class="err">This report draws its charts and tables with JavaScript (no network needed); please enable it.</p></noscript>
<div id="app"></div>
<script type="application/json" id="results">)HTML";

const char* kTail = R"HTML(</script>
<script>
"use strict";
const R = JSON.parse(document.getElementById("results").textContent);
const S = R.scenes[0];
const app = document.getElementById("app");
const problems = [];
// Methods' colours: never the EEVEE curve's orange (nor the Pareto front's black).
const PALETTE = ["#555555","#1f77b4","#2ca02c","#d62728","#9467bd","#8c564b","#e377c2","#17becf","#bcbd22","#393b79"];
const colour = {};
S.methods.forEach((m, i) => colour[m.name] = PALETTE[i % PALETTE.length]);
const EEVEE = "#ff7f0e";
const esc = s => String(s).replace(/[&<>"']/g, c => ({"&":"&amp;","<":"&lt;",">":"&gt;",'"':"&quot;","'":"&#39;"}[c]));
const fin = v => typeof v === "number" && isFinite(v);
const fmt = (v, d) => fin(v) ? v.toFixed(d) : "–";
const short = v => fin(v) ? String(+v.toPrecision(6)) : esc(String(v));  // Blender's float32 settings: 0.2, not 0.20000000298
const ms = v => fin(v) ? (v * 1000 < 10 ? (v * 1000).toFixed(2) : (v * 1000).toFixed(1)) : "–";
const eq = m => fin(m.equivalent_eevee_samples) ? m.equivalent_eevee_samples.toFixed(2) : (m.equivalent_note || "–");
function h(html) { const d = document.createElement("div"); d.innerHTML = html; app.appendChild(d); return d; }

// ---- charts (inline SVG) ----
function niceTicks(lo, hi, n) {
  const span = hi - lo || 1, step0 = span / n, mag = Math.pow(10, Math.floor(Math.log10(step0)));
  const step = [1, 2, 5, 10].map(k => k * mag).find(s => span / s <= n) || 10 * mag;
  const out = [];
  for (let v = Math.ceil(lo / step) * step; v <= hi + 1e-9; v += step) out.push(+v.toFixed(10));
  return out;
}
function logTicks(lo, hi) {
  for (const ks of [[1, 2, 5], [1, 1.5, 2, 3, 5, 7]]) {
    const out = [];
    for (let e = Math.floor(Math.log10(lo)); e <= Math.ceil(Math.log10(hi)); e++)
      for (const k of ks) { const v = +(k * Math.pow(10, e)).toPrecision(6); if (v >= lo && v <= hi) out.push(v); }
    if (out.length >= 3 || ks.length > 3) return out.length >= 3 ? out : niceTicks(lo, hi, 6).filter(v => v > 0);
  }
}
function tickLabel(v) { return v >= 1 ? +v.toPrecision(3) + " s" : +(v * 1000).toPrecision(3) + " ms"; }
// Points no other point beats on both time (lower) and the figure (higher if up, else lower).
function paretoFront(points, up) {
  const better = (a, b) => a.x <= b.x && (up ? a.y >= b.y : a.y <= b.y) && (a.x < b.x || a.y !== b.y);
  return points.filter(p => !points.some(q => q !== p && better(q, p))).sort((a, b) => a.x - b.x);
}
// series: {name, colour, points: [{x, y, label, ring}], line, dash, marker}
function chart(title, xlabel, ylabel, series, opt) {
  opt = opt || {};
  const W = opt.w || 700, H = opt.h || 420, L = 62, Rm = 130, T = 28, B = 46;
  const pts = series.flatMap(s => s.points).filter(p => fin(p.x) && fin(p.y) && (!opt.logx || p.x > 0));
  if (!pts.length) return "<svg width='" + W + "' height='60'><text x='10' y='30'>" + esc(title) + ": no data</text></svg>";
  let x0 = Math.min(...pts.map(p => p.x)), x1 = Math.max(...pts.map(p => p.x));
  let y0 = Math.min(...pts.map(p => p.y)), y1 = Math.max(...pts.map(p => p.y));
  if (opt.logx) { x0 /= 1.35; x1 *= 1.35; } else { const d = (x1 - x0) || 1; x0 -= d * 0.05; x1 += d * 0.05; }
  const dy = (y1 - y0) || Math.abs(y1) || 1; y0 -= dy * 0.08; y1 += dy * 0.08;
  const X = v => L + (opt.logx ? Math.log(v / x0) / Math.log(x1 / x0) : (v - x0) / (x1 - x0)) * (W - L - Rm);
  const Y = v => T + (1 - (v - y0) / (y1 - y0)) * (H - T - B);
  let s = `<svg xmlns="http://www.w3.org/2000/svg" width="${W}" height="${H}" role="img" aria-label="${esc(title)}">`;
  s += `<text class="t" x="${L}" y="16">${esc(title)}</text>`;
  const xt = opt.logx ? logTicks(x0, x1) : niceTicks(x0, x1, 8);
  for (const v of xt) s += `<line x1="${X(v)}" x2="${X(v)}" y1="${T}" y2="${H - B}" stroke="#eee"/><text x="${X(v)}" y="${H - B + 14}" text-anchor="middle">${opt.xfmt ? opt.xfmt(v) : tickLabel(v)}</text>`;
  for (const v of niceTicks(y0, y1, 7)) s += `<line x1="${L}" x2="${W - Rm}" y1="${Y(v)}" y2="${Y(v)}" stroke="#eee"/><text x="${L - 6}" y="${Y(v) + 4}" text-anchor="end">${+v.toFixed(4)}</text>`;
  s += `<rect x="${L}" y="${T}" width="${W - L - Rm}" height="${H - T - B}" fill="none" stroke="#999"/>`;
  s += `<text x="${(L + W - Rm) / 2}" y="${H - 8}" text-anchor="middle">${esc(xlabel)}</text>`;
  s += `<text transform="translate(14 ${(T + H - B) / 2}) rotate(-90)" text-anchor="middle">${esc(ylabel)}</text>`;
  const placed = [];
  for (const se of series) {
    const p = se.points.filter(q => fin(q.x) && fin(q.y) && (!opt.logx || q.x > 0));
    if (se.line && p.length > 1)
      s += `<polyline fill="none" stroke="${se.colour}" stroke-width="${se.width || 2}" ${se.dash ? `stroke-dasharray="${se.dash}"` : ""} points="${p.map(q => X(q.x) + "," + Y(q.y)).join(" ")}"/>`;
    if (se.marker !== false)
      for (const q of p) {
        // Labels: first free spot among a few offsets, so close points stay readable.
        const lw = 6.2 * String(q.label || "").length, px = X(q.x), py = Y(q.y);
        let spot = null;
        for (const [dx, dy] of [[7, -6], [7, 12], [-7 - lw, -6], [-7 - lw, 12], [7, -18], [7, 24], [-7 - lw, -18], [-7 - lw, 24]]) {
          const box = {x: px + dx, y: py + dy - 10, w: lw, h: 12};
          if (!placed.some(b => box.x < b.x + b.w && b.x < box.x + box.w && box.y < b.y + b.h && b.y < box.y + box.h)) { spot = box; break; }
        }
        if (q.label && spot) { placed.push(spot); q.lx = spot.x; q.ly = spot.y + 10; }
        if (q.ring) s += `<circle cx="${X(q.x)}" cy="${Y(q.y)}" r="8" fill="none" stroke="#000" stroke-width="1.5"/>`;
        s += `<circle cx="${X(q.x)}" cy="${Y(q.y)}" r="${se.r || 4.5}" fill="${se.colour}"><title>${esc(q.label || se.name)}: ${q.x.toPrecision(4)}, ${q.y.toPrecision(4)}</title></circle>`;
        if (q.label && q.lx !== undefined) s += `<text x="${q.lx}" y="${q.ly}">${esc(q.label)}</text>`;
      }
  }
  if (opt.legend !== false) {
    let ly = T + 6;
    for (const se of series) {
      if (!se.legend) continue;
      s += `<rect x="${W - Rm + 10}" y="${ly}" width="10" height="10" fill="${se.colour}"/><text x="${W - Rm + 24}" y="${ly + 9}">${esc(se.legend)}</text>`;
      ly += 16;
    }
  }
  return s + "</svg>";
}

const ok = S.methods.filter(m => !m.error && fin(m.mean.psnr));
function tradeoff(key, label, up) {
  const curve = S.eevee_curve.filter(c => fin(c[key]) && fin(c.time_s));
  const all = [...ok.map(m => ({x: m.mean.time_s, y: m.mean[key], name: m.name})),
               ...curve.map(c => ({x: c.time_s, y: c[key], name: "eevee-" + c.samples}))].filter(p => fin(p.x) && fin(p.y));
  const front = paretoFront(all, up), on = new Set(front.map(p => p.name));
  const series = [{name: "EEVEE", colour: EEVEE, line: true, legend: "EEVEE curve",
                   points: curve.map(c => ({x: c.time_s, y: c[key], label: c.samples + " spp", ring: on.has("eevee-" + c.samples)}))}];
  series.push({name: "Pareto front", colour: "#000", line: true, dash: "5 4", width: 1, marker: false, legend: "Pareto front", points: front});
  for (const m of ok) series.push({name: m.name, colour: colour[m.name], legend: m.name,
    points: [{x: m.mean.time_s, y: m.mean[key], label: m.name, ring: on.has(m.name)}]});
  return chart(label + " against time per frame", "time per frame (render + filter), log scale", label + (up ? " (higher is better)" : " (lower is better)"), series, {logx: true});
}
function perFrame(key, label) {
  const series = ok.map(m => ({name: m.name, colour: colour[m.name], line: true, r: 3, legend: m.name,
    points: m.frames.map(f => ({x: f.frame, y: f[key]}))}));
  return chart(label + " per frame", "frame", label, series, {logx: false, xfmt: v => Number.isInteger(v) ? String(v) : ""});
}

// EEVEE's own cost: a least-squares line through the curve's (samples, time per frame).
function perSample() {
  const pts = S.eevee_curve.filter(c => fin(c.time_s)).map(c => [c.samples, c.time_s]);
  if (pts.length < 2) return "";
  const n = pts.length, mx = pts.reduce((a, p) => a + p[0], 0) / n, my = pts.reduce((a, p) => a + p[1], 0) / n;
  const sxx = pts.reduce((a, p) => a + (p[0] - mx) ** 2, 0);
  if (!(sxx > 0)) return "";
  const slope = pts.reduce((a, p) => a + (p[0] - mx) * (p[1] - my), 0) / sxx;
  // A short run on a busy machine can time more samples faster: no negative cost, nor a negative frame.
  if (!(slope > 0 && my - slope * (mx - 1) > 0))
    return " EEVEE's times here do not grow with the sample count (too few frames, or too noisy, for a cost per sample).";
  return ` EEVEE here: about ${ms(my - slope * (mx - 1))} ms for a 1-sample frame and ${ms(slope)} ms per further sample (a line through the curve's times).`;
}
const meansOver = S.means_over_frames || S.frames;
const warmup = meansOver[0] - S.frames[0];
const temporalListed = S.methods.some(m => m.temporal);
// Every frame-to-frame figure of the entries that are not temporal is 0: a still scene's repeated frames.
const stillFrames = temporalListed && S.frames[1] > S.frames[0] &&
  S.methods.filter(m => !m.temporal && !m.error).concat(S.eevee_curve).every(m => (m.mean || m).temporal_error === 0);

// ---- the page ----
const failed = S.methods.filter(m => m.error);
h(`<h1>Crisp: anti-aliasing error against run time</h1>
<p class="sub">Scene <b>${esc(S.name)}</b>${S.blender_scene && S.blender_scene !== S.name ? ` (its scene <b>${esc(S.blender_scene)}</b>)` : ""}, ${S.resolution[0]}&times;${S.resolution[1]}, frames ${S.frames[0]}–${S.frames[1]},
reference = EEVEE ${S.reference.samples} samples (${fmt(S.reference.time_s, 2)} s per frame)${S.reference.samples < 256 ? ", fewer than the 256 METHODS.md asks of final figures: read these as a quick run's" : ""}.
Every method filters a 1-sample render (the temporal methods a jittered one, rsaa one with its geometry passes: column "input"); time per frame = that render + the filter.${perSample()}</p>` +
  (failed.length ? `<p class="err">Failed (details in the table): ${failed.map(m => esc(m.name) + " (" + esc(m.error.length > 90 ? m.error.slice(0, 90) + "…" : m.error) + ")").join("; ")}</p>` : ""));

let rows = "";
const best = Math.max(...ok.map(m => m.mean.psnr));
for (const m of S.methods) {
  rows += `<tr class="${m.error ? "fail" : (m.mean.psnr === best ? "best" : "")}"><td class="l"><i style="display:inline-block;width:10px;height:10px;background:${colour[m.name]}"></i> ${esc(m.name)}${m.temporal ? " <small>(temporal)</small>" : ""}${m.panel ? " <small>(the scene's Crisp panel)</small>" : ""}</td>
<td>${fmt(m.mean.psnr, 2)}</td><td>${fmt(m.mean.ssim, 4)}</td><td>${fmt(m.mean.perceptual_error, 4)}</td><td>${fmt(m.mean.temporal_error, 5)}</td>
<td>${m.error ? "–" : ms(m.mean.render_s)}</td><td>${ms(m.mean.filter_s)}</td><td>${ms(m.mean.time_s)}</td><td>${eq(m)}</td><td>${m.pareto ? "&#9679;" : ""}</td>
<td class="l">${m.error ? "<span class=err>FAILED: " + esc(m.error) + "</span>" : esc(m.input)}</td></tr>`;
}
let crow = "";
for (const c of S.eevee_curve)
  crow += `<tr><td class="l">EEVEE ${c.samples} spp</td><td>${fmt(c.psnr, 2)}</td><td>${fmt(c.ssim, 4)}</td><td>${fmt(c.perceptual_error, 4)}</td><td>${fmt(c.temporal_error, 5)}</td><td>${ms(c.time_s)}</td><td></td><td>${ms(c.time_s)}</td><td>${c.samples}</td><td>${c.pareto ? "&#9679;" : ""}</td><td class="l">${esc(c.input)}</td></tr>`;
const THEAD = `<tr><th class="l">method</th><th>PSNR dB</th><th>SSIM</th><th>perceptual error</th><th>temporal error</th><th>render ms</th><th>filter ms</th><th>time/frame ms</th><th>equivalent EEVEE samples</th><th>Pareto</th><th class="l">input / status</th></tr>`;
h(`<h2>Headline</h2><table id="headline">${THEAD}${rows}${crow}</table>
<p class="sub">Error figures: ${meansOver[0] === meansOver[1] ? `frame ${meansOver[0]} alone` : `means over frames ${meansOver[0]}–${meansOver[1]} (PSNR: the mean of the per-frame dB)`}${warmup > 0 ? `; ${warmup > 1 ? `the first ${warmup} frames` : "the first frame"}, the temporal methods' warm-up, ${warmup > 1 ? "are" : "is"} left out of them (--warmup) and shown per frame below` : temporalListed && S.frames[1] > S.frames[0] ? "; they include the temporal methods' first frames, where their history starts from one sample (--warmup leaves such frames out)" : ""}.
Times: medians over every frame (per-frame values below and in results.json); renders of the same samples and passes (EEVEE 1 spp and a colour-only jittered render) are timed as one, each frame's time the mean of theirs, so that the machine's noise does not rank the same work apart; blender-smaa's filter time includes Blender loading and writing the image, the library methods' does not; a temporal method's includes rebuilding its motion vectors from depth and the sidecars where the renderer wrote none (EEVEE 3.4).
Higher PSNR/SSIM is better; lower perceptual error (FLIP-style, 0–1) and temporal error are better. SSIM: Wang et al. 2004 (11&times;11 Gaussian, &sigma; 1.5) of the luma, the image mirrored at its borders.${stillFrames ? " Here the spatial methods' and EEVEE's frames repeat (their temporal error is 0: nothing moves or changes), so that column ranks only the temporal methods, by how much they still change as they converge." : ""}
"Equivalent EEVEE samples": the sample count at which EEVEE's own curve reaches the method's PSNR (log<sub>2</sub> samples interpolated linearly against PSNR).
Pareto: no other point (method or EEVEE sample count) is as fast or faster and as high or higher in PSNR, and better in one of the two.</p>`);
if (S.geometric_edges && S.geometric_edges.frames_with_edges > 0) {
  let erow = "";
  for (const m of S.methods.concat(S.eevee_curve)) {
    const mean = m.mean || {};
    erow += `<tr><td class="l">${m.kind === "eevee" ? "EEVEE " + m.samples + " spp" : esc(m.name)}</td><td>${fmt(mean.psnr, 2)}</td><td>${fmt(mean.psnr_geometric_edges, 2)}</td><td>${ms(mean.geometry_render_s)}</td><td>${m.kind === "eevee" ? "" : ms(mean.filter_s)}</td></tr>`;
  }
  h(`<h2>Geometric edges</h2><table id="edges"><tr><th class="l">method</th><th>PSNR dB (all pixels)</th><th>PSNR dB (geometric-edge pixels)</th><th>geometry renders ms</th><th>filter ms</th></tr>${erow}</table>
<p class="sub">Geometric-edge pixels: ${esc(S.geometric_edges.definition)} (map: images/maps/geometric_edges.png). Geometry renders: rsaa's 8 extra depth + normal renders per frame, reported apart from the filter and included in its time per frame above.</p>`);
}

h(`<h2>Error against run time</h2><div class="charts"><div class="chart">${tradeoff("psnr", "PSNR (dB)", true)}</div>
<div class="chart">${tradeoff("perceptual_error", "perceptual error", false)}</div></div>
<p class="sub">Orange line: EEVEE at 1, 2, 4, … samples (its time: that many samples' render). Dots: methods (their time: the 1-sample render + the filter, + rsaa's geometry renders). Rings and the dashed line: the Pareto front of each chart (nothing else is as fast and as good, and better in one).</p>`);

h(`<h2>Per frame</h2><div class="charts"><div class="chart">${perFrame("psnr", "PSNR (dB)")}</div>
<div class="chart">${perFrame("temporal_error", "temporal error")}</div></div>
<p class="sub">Temporal error (METHODS.md): mean over valid pixels of |(out<sub>t</sub> − W(out<sub>t−1</sub>)) − (ref<sub>t</sub> − W(ref<sub>t−1</sub>))| on display-encoded RGB; W: ${esc(S.temporal_error_warp)}. It is high where a method flickers more (or less) than the reference.</p>`);

// Crops + flip-book.
const frames = [];
for (let f = S.frames[0]; f <= S.frames[1]; f++) frames.push(f);
const order = ["reference", ...S.methods.map(m => m.name)];
const caption = n => n === "reference" ? `reference (${S.reference.samples} spp)` : n === "none" ? "none (1 sample)" : n;
const zoom0 = S.crops.length ? Math.max(2, Math.min(12, Math.round(220 / S.crops[0].size))) : 4;
let cropHtml = `<div class="controls"><button id="play">pause</button> frame <input type="range" id="slider" min="0" max="${frames.length - 1}" value="0"> <span id="frameLabel"></span>
&nbsp; zoom <select id="zoom">${[2, 3, 4, 6, 8, 12, 16].map(z => `<option${z === zoom0 ? " selected" : ""}>${z}</option>`).join("")}</select>&times; (nearest neighbour)</div>`;
S.crops.forEach((c, k) => {
  cropHtml += `<h3>Place ${k + 1}: x ${c.x}, y ${c.y}, ${c.size}&times;${c.size} px (1-sample mean squared error per frame ${c.score.toExponential(2)})</h3><div class="crop">`;
  for (const n of order) {
    const files = c.files[n];
    if (!files || !files.length) continue;
    cropHtml += `<figure><img class="px crop-img" data-crop="${k}" data-name="${esc(n)}" src="${esc(files[0])}" width="${c.size * zoom0}" height="${c.size * zoom0}" alt="${esc(n)}"><figcaption>${esc(caption(n))}</figcaption></figure>`;
  }
  cropHtml += "</div>";
});
h(`<h2>The most aliased places, as a flip-book</h2><p class="sub">Chosen automatically: the ${S.crops.length} non-overlapping windows with the largest 1-sample error (its mean over the frames). Playing the frames shows flicker and crawling.</p>` + cropHtml);

let playing = true, idx = 0;
function show(i) {
  idx = i;
  document.getElementById("slider").value = i;
  document.getElementById("frameLabel").textContent = "frame " + frames[i];
  for (const img of document.querySelectorAll("img.crop-img")) {
    const list = S.crops[+img.dataset.crop].files[img.dataset.name];
    if (list && list[i]) img.src = list[i];
  }
}
document.getElementById("slider").addEventListener("input", e => { playing = false; document.getElementById("play").textContent = "play"; show(+e.target.value); });
document.getElementById("play").addEventListener("click", e => { playing = !playing; e.target.textContent = playing ? "pause" : "play"; });
document.getElementById("zoom").addEventListener("change", e => {
  for (const img of document.querySelectorAll("img.crop-img")) { const c = S.crops[+img.dataset.crop]; img.width = img.height = c.size * +e.target.value; }
});
show(0);
setInterval(() => { if (playing && frames.length > 1) show((idx + 1) % frames.length); }, 400);

// Full frames and maps.
let grid = `<figure><img class="px" src="images/full/reference.png" alt="reference"><figcaption>reference (${S.reference.samples} spp)</figcaption></figure>`;
for (const m of S.methods) if (!m.error) grid += `<figure><img class="px" src="images/full/${esc(m.name)}.png" alt="${esc(m.name)}"><figcaption>${esc(caption(m.name))}</figcaption></figure>`;
let maps = "";
const mapKinds = ["error", "ssim", "perceptual"].concat(S.frames[1] > S.frames[0] ? ["temporal"] : []);  // temporal: 2+ frames
for (const m of S.methods) {
  if (m.error) continue;
  maps += `<tr><td class="l">${esc(m.name)}</td>` + mapKinds.map(k =>
    `<td><img class="px" style="width:320px" src="images/maps/${esc(m.name)}_${k}.png" alt="${esc(m.name)} ${k}"></td>`).join("") + "</tr>";
}
h(`<h2>Frame ${S.map_frame}: images, error and SSIM maps</h2><div class="grid">${grid}</div>
<h3>Maps (dark = good; colour scale black&rarr;purple&rarr;red&rarr;yellow&rarr;white)</h3>
<table><tr><th class="l">method</th><th>error, RMS over RGB (0 – 0.25 in sRGB units)</th><th>1 − SSIM (0 – 1)</th><th>perceptual error (0 – 1)</th>${S.frames[1] > S.frames[0] ? "<th>temporal error, mean over all frames (0 – 0.05 in sRGB units)</th>" : ""}</tr>${maps}</table>`);

// Every figure.
let all = `<tr><th class="l">kind</th><th class="l">name</th><th>frame</th><th>PSNR</th><th>SSIM</th><th>perceptual</th><th>temporal</th><th>render ms</th><th>filter ms</th><th>time ms</th><th class="l">file</th></tr>`;
for (const e of [...S.methods, ...S.eevee_curve])
  for (const f of e.frames)
    all += `<tr><td class="l">${e.kind}</td><td class="l">${esc(e.name)}</td><td>${f.frame}</td><td>${fmt(f.psnr, 3)}</td><td>${fmt(f.ssim, 5)}</td><td>${fmt(f.perceptual_error, 5)}</td><td>${fmt(f.temporal_error, 6)}</td><td>${ms(f.render_s)}</td><td>${ms(f.filter_s)}</td><td>${ms(f.time_s)}</td><td class="l"><a href="${esc(f.file)}">${esc(f.file)}</a></td></tr>`;
h(`<h2>Every figure</h2><details><summary>Per frame, every method and EEVEE sample count (also in results.json and results.csv)</summary><table>${all}</table></details>`);

// Provenance.
const smaa = S.smaa || {};
h(`<h2>How this was made</h2><table>
<tr><th class="l">command</th><td class="l"><code>${esc(R.command)}</code></td></tr>
<tr><th class="l">versions</th><td class="l">crisp ${esc(R.versions.crisp)}, Blender ${esc(R.versions.blender)}, OpenImageIO ${esc(R.versions.oiio)}</td></tr>
<tr><th class="l">machine</th><td class="l">${esc(R.machine.cpu)}, ${R.machine.cores} cores, ${esc(R.machine.os)}; library threads ${R.threads || "all"}</td></tr>
<tr><th class="l">run time</th><td class="l">Blender renders ${fmt(R.run_seconds.blender, 1)} s (this run; resumed frames not re-rendered), methods + measurements ${fmt(R.run_seconds.methods_and_measures, 1)} s</td></tr>
<tr><th class="l">metrics</th><td class="l">${esc(R.metrics_note)}</td></tr>
<tr><th class="l">blender-smaa</th><td class="l">Blender's compositor Anti-Aliasing node (SMAA 1×) on the 1-sample frames: node threshold ${short(smaa.threshold)} (= SMAA threshold ${short(smaa.smaa_threshold)}), contrast limit ${short(smaa.contrast_limit)}, corner rounding ${short(smaa.corner_rounding)}; its time includes loading and writing the image. ${esc(smaa.note || "")}</td></tr>
${S.panel ? `<tr><th class="l">Crisp panel</th><td class="l">${esc(S.panel.line)}${S.panel.row ? ` (row <b>${esc(S.panel.row)}</b>)` : ""}</td></tr>` : ""}
<tr><th class="l">temporal inputs</th><td class="l">jitter ${esc(S.jitter_distribution)}${S.panel && S.panel.from_panel.jitter ? " (the scene's Crisp panel's)" : ""} (Halton 2,3); sidecar y up, passed to the library as jitterY = −y${fin(S.filter_size) ? `; Film &gt; Filter Size ${short(S.filter_size)} px (the Blackman-Harris jitter's spread, EEVEE's pixel filter and the temporal methods' filterSize, unless their settings give one)` : ""}</td></tr>
</table><details><summary>Pass plans</summary><pre>${esc(JSON.stringify(S.plans, null, 1))}</pre></details>`);

// Self-check: every image decoded, every chart drawn.
window.addEventListener("load", () => {
  for (const img of document.images) if (!img.complete || img.naturalWidth === 0) problems.push("image not loaded: " + img.getAttribute("src"));
  if (document.querySelectorAll(".chart svg").length < 4) problems.push("charts missing");
  if (!document.querySelectorAll("#headline tr").length) problems.push("headline table missing");
  for (const p of problems) console.error("report self-check: " + p);
  document.title = (problems.length ? "crisp eval report: PROBLEMS: " + problems.join("; ") : "crisp eval report: OK") + " - " + S.name;
});
</script></body></html>
)HTML";

}  // namespace

void writeReport(const std::string& outDir, const nlohmann::json& results) {
  std::string data = results.dump();
  // Inside <script>, "</" could end the element early, and "<!--" followed by "<script" would make
  // the HTML parser read past the element's end (a scene named after such a .blend left the page
  // empty). '<' only occurs inside JSON strings, where \u003c is the same character to JSON.parse.
  std::string safe;
  safe.reserve(data.size());
  for (char c : data) {
    if (c == '<') safe += "\\u003c";
    else safe += c;
  }
  cli::writeTextFile(cli::joinPath(outDir, "report.html"), std::string(kHead) + safe + kTail);
}

}  // namespace crisp::eval
