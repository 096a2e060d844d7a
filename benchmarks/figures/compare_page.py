"""The interactive comparison page: one self-contained HTML file (no network, no library) with the full
table of a comparison grid, sortable by any column and filtered by scenario, metric, tuning, backend and
method, and k_hat(t) against the truth for every scenario, drawn as inline SVG by a few lines of script
from the page's own data. The rest of the report (identifiability, paired comparisons, settings) comes
as static tables.

The page reads its state from the address's fragment (``#sort=value&dir=desc&metric=vaf_stiffness``), so
a view can be linked; after drawing, ``body`` carries ``data-rows`` (rows shown) and ``data-plots`` (plots
drawn), which the browser test reads (tests/test_comparison_page.py).
"""
from __future__ import annotations

import html
import json
import math

import numpy as np
import pandas as pd

#: columns of the page's table: (key in the full table, header)
COLUMNS = (("cell", "scenario"), ("backend", "backend"), ("method", "method"), ("tuning", "tuning"),
           ("metric", "metric"), ("value", "value"), ("lo", "interval lo"), ("hi", "interval hi"),
           ("rank", "rank"), ("ranked", "of"), ("n", "n"), ("note", "note"), ("settings", "settings"))
NUMERIC = {"value", "lo", "hi", "rank", "ranked", "n"}
#: methods per plot drawn with their band over realizations (the others: the mean only)
BANDS = 3


def _num(v):
    """A number for the page's data: 4 significant digits; infinities as the strings 'inf'/'-inf';
    NaN as null."""
    if v is None:
        return None
    v = float(v)
    if math.isnan(v):
        return None
    if math.isinf(v):
        return "inf" if v > 0 else "-inf"
    return float(f"{v:.4g}")


def _series(y) -> list:
    return [None if not np.isfinite(v) else float(f"{v:.4g}") for v in np.asarray(y, float)]


def _time(t) -> dict:
    """A time axis: start, step and count when uniform (the stored curves are), else the samples."""
    t = np.asarray(t, float)
    if t.size > 2 and np.allclose(np.diff(t), t[1] - t[0], rtol=1e-6, atol=1e-9):
        return {"t0": float(f"{t[0]:.6g}"), "dt": float(f"{t[1] - t[0]:.6g}"), "n": int(t.size)}
    return {"t": [float(f"{x:.6g}") for x in t]}


def page_data(table: pd.DataFrame, curves: dict, order: dict | None = None) -> dict:
    """The page's data: the table's rows as arrays in :data:`COLUMNS` order, and per (cell, backend,
    tuning) plot the truth and every method's mean (with its band over realizations for the
    :data:`BANDS` best by median VAF of k, when the curves carry it). ``curves``: (cell, backend,
    tuning) -> the sets of :func:`compare_plots.curve_sets`; ``order``: the same key -> methods best
    first."""
    rows = []
    for rec in table.to_dict("records"):
        rows.append([_num(rec.get(k)) if k in NUMERIC else ("" if pd.isna(rec.get(k)) else str(rec.get(k)))
                     for k, _ in COLUMNS])
    plots = []
    for (cell, backend, tuning), d in curves.items():
        best = (order or {}).get((cell, backend, tuning), [])
        methods = []
        for m, s in sorted(d["methods"].items(), key=lambda kv: (best.index(kv[0]) if kv[0] in best else 1e9,
                                                                  kv[0])):
            e = {"name": m, "time": _time(s["t"]), "mean": _series(s["mean"])}
            if "lo" in s and m in best[:BANDS]:
                e["lo"], e["hi"] = _series(s["lo"]), _series(s["hi"])
            methods.append(e)
        plots.append({"cell": cell, "backend": backend, "tuning": tuning, "time": _time(d["t"]),
                      "truth": _series(d["truth"]), "methods": methods})
    return {"columns": [h for _, h in COLUMNS], "keys": [k for k, _ in COLUMNS], "rows": rows, "plots": plots}


def _table_html(title: str, df: pd.DataFrame) -> str:
    if df is None or df.empty:
        return ""
    head = "".join(f"<th>{html.escape(str(c))}</th>" for c in df.columns)
    body = []
    for rec in df.itertuples(index=False):
        cells = []
        for v in rec:
            if isinstance(v, (float, np.floating)):
                v = "" if math.isnan(v) else f"{v:.4g}"
            cells.append(f"<td>{html.escape(str(v))}</td>")
        body.append("<tr>" + "".join(cells) + "</tr>")
    return (f"<h3>{html.escape(title)}</h3><div class='wide'><table class='static'><thead><tr>{head}</tr></thead>"
            f"<tbody>{''.join(body)}</tbody></table></div>")


STYLE = """
body{font:14px/1.4 system-ui,sans-serif;margin:1.5em;color:#222;max-width:1400px}
h1{font-size:1.5em} h2{font-size:1.2em;margin-top:1.6em} h3{font-size:1em}
table{border-collapse:collapse;font-size:12px} td,th{border:1px solid #ccc;padding:2px 6px;text-align:left}
th{background:#f0f0f0;position:sticky;top:0} #full th{cursor:pointer;user-select:none}
#full th.asc::after{content:" \\25B2"} #full th.desc::after{content:" \\25BC"}
td.num{text-align:right;font-variant-numeric:tabular-nums} .wide{overflow-x:auto;max-height:70vh;overflow-y:auto}
.filters label{margin-right:1em} .plots{display:flex;flex-wrap:wrap;gap:12px}
.plot{border:1px solid #ddd;padding:4px} .plot h4{margin:0;font-size:12px;font-weight:normal}
.legend span{display:inline-block;margin-right:8px;font-size:11px;cursor:pointer} .legend span.off{opacity:.35}
.note{color:#555}
"""

SCRIPT = r"""
(function(){
const D = JSON.parse(document.getElementById('data').textContent);
const NUM = new Set(['value','interval lo','interval hi','rank','of','n']);
const $ = id => document.getElementById(id);
const state = {sort: null, dir: 1};
const num = v => v === null || v === '' ? NaN : v === 'inf' ? Infinity : v === '-inf' ? -Infinity : +v;
const fmt = v => v === null ? '' : v === 'inf' ? '\u221e' : v === '-inf' ? '-\u221e' :
  typeof v === 'number' ? (Math.abs(v) >= 1e4 ? v.toExponential(2) : +v.toPrecision(4) + '') : v;
function options(sel, values){
  for (const v of values){ const o = document.createElement('option'); o.value = o.textContent = v; sel.appendChild(o); }
}
const col = name => D.columns.indexOf(name);
options($('f-scenario'), [...new Set(D.rows.map(r => r[col('scenario')]))]);
options($('f-metric'), [...new Set(D.rows.map(r => r[col('metric')]))]);
options($('f-tuning'), [...new Set(D.rows.map(r => r[col('tuning')]))]);
options($('f-backend'), [...new Set(D.rows.map(r => r[col('backend')]))]);
const head = $('full').querySelector('thead tr');
D.columns.forEach((c, i) => {
  const th = document.createElement('th'); th.textContent = c; th.dataset.col = i;
  th.addEventListener('click', () => { state.dir = state.sort === i ? -state.dir : 1; state.sort = i; draw(); });
  head.appendChild(th);
});
function keep(r){
  for (const [id, c] of [['f-scenario','scenario'],['f-metric','metric'],['f-tuning','tuning'],['f-backend','backend']]){
    const v = $(id).value; if (v && r[col(c)] !== v) return false;
  }
  const q = $('f-method').value.trim().toLowerCase();
  return !q || r[col('method')].toLowerCase().includes(q);
}
function draw(){
  let rows = D.rows.filter(keep);
  if (state.sort !== null){
    const i = state.sort, numeric = NUM.has(D.columns[i]);
    rows = rows.map((r, k) => [r, k]).sort((a, b) => {
      let x = a[0][i], y = b[0][i];
      if (numeric){ x = num(x); y = num(y);
        if (isNaN(x) || isNaN(y)) return (isNaN(x) - isNaN(y)) || a[1] - b[1];   // blanks last
        return (x < y ? -1 : x > y ? 1 : 0) * state.dir || a[1] - b[1]; }
      return String(x).localeCompare(String(y)) * state.dir || a[1] - b[1];
    }).map(p => p[0]);
  }
  head.querySelectorAll('th').forEach((th, i) => th.className = i === state.sort ? (state.dir > 0 ? 'asc' : 'desc') : '');
  const body = $('full').querySelector('tbody'); body.textContent = '';
  const frag = document.createDocumentFragment();
  for (const r of rows){
    const tr = document.createElement('tr');
    r.forEach((v, i) => { const td = document.createElement('td'); td.textContent = fmt(v);
      if (NUM.has(D.columns[i])){ td.className = 'num'; td.dataset.v = v === null ? '' : v; } tr.appendChild(td); });
    frag.appendChild(tr);
  }
  body.appendChild(frag);
  $('count').textContent = rows.length + ' of ' + D.rows.length + ' rows';
  document.body.dataset.rows = rows.length;
  plots();
}
const SVG = 'http://www.w3.org/2000/svg';
const el = (n, a) => { const e = document.createElementNS(SVG, n); for (const k in a) e.setAttribute(k, a[k]); return e; };
const COLORS = ['#1f77b4','#ff7f0e','#2ca02c','#d62728','#9467bd','#8c564b','#e377c2','#7f7f7f','#bcbd22','#17becf',
                '#aec7e8','#ffbb78','#98df8a','#ff9896','#c5b0d5','#c49c94','#f7b6d2','#c7c7c7','#dbdb8d','#9edae5'];
const times = T => T.t || Array.from({length: T.n}, (_, k) => T.t0 + k * T.dt);
function plot(P){
  const W = 420, H = 250, L = 46, R = 8, T = 8, B = 30;
  const svg = el('svg', {width: W, height: H, viewBox: `0 0 ${W} ${H}`, class: 'khat'});
  const tt = times(P.time), truth = P.truth.filter(v => v !== null);
  const lo = Math.min(...truth), hi = Math.max(...truth), pad = Math.max(0.6 * (hi - lo), 0.2 * Math.abs(hi));
  const y0 = lo - pad, y1 = hi + pad, x0 = tt[0], x1 = tt[tt.length - 1];
  const X = x => L + (x - x0) / (x1 - x0) * (W - L - R), Y = y => T + (y1 - Math.min(y1, Math.max(y0, y))) / (y1 - y0) * (H - T - B);
  svg.appendChild(el('rect', {x: L, y: T, width: W - L - R, height: H - T - B, fill: 'none', stroke: '#999'}));
  for (let k = 0; k <= 4; k++){
    const yv = y0 + k * (y1 - y0) / 4, xv = x0 + k * (x1 - x0) / 4;
    const a = el('text', {x: L - 4, y: Y(yv) + 3, 'text-anchor': 'end', 'font-size': 10}); a.textContent = +yv.toPrecision(3); svg.appendChild(a);
    const b = el('text', {x: X(xv), y: H - B + 12, 'text-anchor': 'middle', 'font-size': 10}); b.textContent = +xv.toPrecision(3); svg.appendChild(b);
  }
  const lab = el('text', {x: (L + W) / 2, y: H - 4, 'text-anchor': 'middle', 'font-size': 10}); lab.textContent = 't (s)'; svg.appendChild(lab);
  const ylab = el('text', {x: 10, y: H / 2, 'font-size': 10, transform: `rotate(-90 10 ${H / 2})`, 'text-anchor': 'middle'});
  ylab.textContent = 'k (N\u00b7m/rad)'; svg.appendChild(ylab);
  const path = (t, y) => { let d = '', pen = false;
    y.forEach((v, k) => { if (v === null){ pen = false; return; } d += (pen ? 'L' : 'M') + X(t[k]).toFixed(1) + ' ' + Y(v).toFixed(1); pen = true; });
    return d; };
  const legend = document.createElement('div'); legend.className = 'legend';
  P.methods.forEach((m, k) => {
    const c = COLORS[k % COLORS.length], t = times(m.time), g = el('g', {'data-method': m.name});
    if (m.lo){ let d = '';
      t.forEach((x, j) => { if (m.hi[j] !== null) d += (d ? 'L' : 'M') + X(x).toFixed(1) + ' ' + Y(m.hi[j]).toFixed(1); });
      for (let j = t.length - 1; j >= 0; j--) if (m.lo[j] !== null) d += 'L' + X(t[j]).toFixed(1) + ' ' + Y(m.lo[j]).toFixed(1);
      g.appendChild(el('path', {d: d + 'Z', fill: c, 'fill-opacity': 0.15, stroke: 'none'})); }
    g.appendChild(el('path', {d: path(t, m.mean), fill: 'none', stroke: c, 'stroke-width': 1.2, class: 'mean'}));
    svg.appendChild(g);
    const s = document.createElement('span'); s.style.color = c; s.textContent = '\u25a0 ' + m.name + (m.lo ? ' (band)' : '');
    s.addEventListener('click', () => { s.classList.toggle('off'); g.style.display = s.classList.contains('off') ? 'none' : ''; });
    legend.appendChild(s);
  });
  svg.appendChild(el('path', {d: path(tt, P.truth), fill: 'none', stroke: '#000', 'stroke-width': 2, class: 'truth'}));
  const s = document.createElement('span'); s.style.color = '#000'; s.textContent = '\u25a0 truth'; legend.prepend(s);
  const box = document.createElement('div'); box.className = 'plot';
  const h = document.createElement('h4'); h.textContent = `${P.cell} (${P.backend}, ${P.tuning})`;
  box.append(h, svg, legend); svg.dataset.rendered = svg.querySelectorAll('path.mean').length > 0 ? '1' : '0';
  return box;
}
let drawn = null;
function plots(){
  const host = $('plots');
  if (drawn === null){ drawn = D.plots.map(P => { const b = plot(P); host.appendChild(b); return [P, b]; }); }
  let shown = 0;
  for (const [P, b] of drawn){
    const ok = [['f-scenario', P.cell], ['f-tuning', P.tuning], ['f-backend', P.backend]].every(([id, v]) => !$(id).value || $(id).value === v);
    b.style.display = ok ? '' : 'none'; shown += ok;
  }
  document.body.dataset.plots = host.querySelectorAll('svg.khat[data-rendered="1"]').length;
  $('plotcount').textContent = shown + ' of ' + D.plots.length + ' plots shown';
}
['f-scenario','f-metric','f-tuning','f-backend','f-method'].forEach(id => $(id).addEventListener('input', draw));
const hash = new URLSearchParams(location.hash.slice(1));
for (const [k, id] of [['scenario','f-scenario'],['metric','f-metric'],['tuning','f-tuning'],['backend','f-backend'],['method','f-method']])
  if (hash.has(k)) $(id).value = hash.get(k);
if (hash.has('sort')){ const i = D.columns.indexOf(hash.get('sort')) >= 0 ? D.columns.indexOf(hash.get('sort')) : D.keys.indexOf(hash.get('sort'));
  if (i >= 0){ state.sort = i; state.dir = hash.get('dir') === 'desc' ? -1 : 1; } }
draw();
})();
"""


def render(title: str, intro: list[str], data: dict, static: list[tuple[str, pd.DataFrame]]) -> str:
    """The page as one HTML string: ``intro`` paragraphs (plain text), the interactive table and plots of
    ``data`` (:func:`page_data`) and the ``static`` tables."""
    blob = json.dumps(data, separators=(",", ":"), allow_nan=False).replace("</", "<\\/")
    paras = "".join(f"<p>{html.escape(p)}</p>" for p in intro)
    statics = "".join(_table_html(t, df) for t, df in static)
    sel = "".join(f"<label>{lab} <select id='f-{key}'><option value=''>all</option></select></label>"
                  for key, lab in (("scenario", "scenario"), ("metric", "metric"), ("tuning", "tuning"),
                                   ("backend", "backend")))
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{html.escape(title)}</title>
<meta name="viewport" content="width=device-width, initial-scale=1"><style>{STYLE}</style></head>
<body data-rows="0" data-plots="0">
<h1>{html.escape(title)}</h1>
{paras}
<h2>The full table</h2>
<p class="note">Click a header to sort (again: reverse); blanks sort last. Filters:</p>
<div class="filters">{sel}<label>method <input id="f-method" type="search" placeholder="contains"></label>
<span id="count"></span></div>
<div class="wide"><table id="full"><thead><tr></tr></thead><tbody></tbody></table></div>
<h2>k&#770;(t) against the truth</h2>
<p class="note">Mean estimate over realizations per method; shaded: 5th to 95th percentile over realizations
(for the {BANDS} methods with the highest median VAF of k, where the run stored it). The scenario, tuning and
backend filters above apply. Click a legend entry to hide its line. <span id="plotcount"></span></p>
<div id="plots" class="plots"></div>
{statics}
<script type="application/json" id="data">{blob}</script>
<script>{SCRIPT}</script>
</body></html>
"""
