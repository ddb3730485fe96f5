// The report's page and CSV (report_page.hpp; what each number means: docs/reports.md).
#include "report_html.hpp"

#include <cmath>
#include <sstream>

namespace softgi::app::report {

namespace {

// The data goes into a <script type="application/json"> element, which "</script" would end early and
// "<!--" followed by "<script" would keep open past its end tag. JSON has '<' only inside strings,
// where \u003c means the same, so every '<' is written that way; U+2028/U+2029 likewise (older
// parsers). JSON.parse reads the text back unchanged.
std::string embeddable(const Json& results) {
  const std::string text = results.dump(-1, ' ', false, Json::error_handler_t::replace);
  std::string out;
  out.reserve(text.size() + 64);
  for (std::size_t i = 0; i < text.size(); ++i) {
    if (text[i] == '<') {
      out += "\\u003c";
    } else if (text.compare(i, 3, "\xE2\x80\xA8") == 0) {
      out += "\\u2028";
      i += 2;
    } else if (text.compare(i, 3, "\xE2\x80\xA9") == 0) {
      out += "\\u2029";
      i += 2;
    } else {
      out += text[i];
    }
  }
  return out;
}

const char* const kHead = R"HTML(<!doctype html>
<html lang="en">
<head>
<meta charset="utf-8">
<title>softgi report</title>
<style>
body { font: 14px/1.45 system-ui, -apple-system, "Segoe UI", sans-serif; margin: 1.5em auto; max-width: 1200px; padding: 0 1em;
       color: #1d2430; background: #fff; }
h1 { font-size: 1.6em; margin-bottom: 0.2em; } h2 { margin-top: 2em; border-bottom: 2px solid #dde3ea; padding-bottom: 0.2em; }
h3 { margin-top: 1.5em; }
code, pre, .mono { font-family: ui-monospace, "DejaVu Sans Mono", monospace; font-size: 12px; }
table { border-collapse: collapse; margin: 0.6em 0; font-size: 13px; }
th, td { border: 1px solid #d4dae1; padding: 3px 7px; text-align: left; vertical-align: top; }
th { background: #f1f4f7; } td.num { text-align: right; font-variant-numeric: tabular-nums; }
tr.failed td { background: #fff0f0; } .floor { color: #8a6d00; } .muted { color: #6b7480; }
.chart { margin: 0.6em 0; } .note { background: #f6f8fa; border-left: 4px solid #8aa4c2; padding: 0.5em 0.9em; }
#page-errors { background: #fff0f0; color: #a00; padding: 0.6em; white-space: pre-wrap; }
.viewer { display: flex; gap: 1.5em; flex-wrap: wrap; align-items: flex-start; }
.compare { position: relative; display: inline-block; line-height: 0; }
.compare img, .flip img { image-rendering: pixelated; width: 384px; height: auto; display: block; }
.compare img.top { position: absolute; left: 0; top: 0; }
.colorbar { width: 384px; height: 14px; margin-top: 6px;
  background: linear-gradient(to right, #000004 0%, #140e36 10%, #3b0f70 20%, #641a80 30%, #8c2981 40%, #b73779 50%,
                              #de4968 60%, #f7705c 70%, #fe9f6d 80%, #fecf92 90%, #fcfdbf 100%); }
.ticks { width: 384px; display: flex; justify-content: space-between; font-size: 12px; line-height: 1.2; }
</style>
<script src="lib/vega.min.js"></script>
<script src="lib/vega-lite.min.js"></script>
<script src="lib/vega-embed.min.js"></script>
</head>
<body data-ready="0" data-errors="0" data-charts="0">
<pre id="page-errors" hidden></pre>
<div id="content"></div>
<script type="application/json" id="softgi-results">)HTML";

const char* const kScript = R"HTML(</script>
<script>
(function () {
  'use strict';
  const errors = [];
  function fail(message) {
    errors.push(String(message));
    const box = document.getElementById('page-errors');
    box.hidden = false;
    box.textContent = errors.join('\n');
    document.body.dataset.errors = String(errors.length);
  }
  // Capture phase: an image or script that fails to load reports here (it does not bubble), and
  // Chromium logs nothing for a missing file:// resource.
  window.addEventListener('error', function (ev) {
    const t = ev.target;
    if (t && (t.tagName === 'IMG' || t.tagName === 'SCRIPT')) fail('could not load ' + (t.src || t.getAttribute('src')));
    else fail(ev.message || ev);
  }, true);
  window.addEventListener('unhandledrejection', function (ev) { fail('unhandled rejection: ' + (ev.reason && ev.reason.message || ev.reason)); });

  const pending = [];
  function el(tag, attrs, children) {
    const e = document.createElement(tag);
    for (const k in (attrs || {})) {
      if (k === 'text') e.textContent = attrs[k]; else if (k === 'html') e.innerHTML = attrs[k]; else e.setAttribute(k, attrs[k]);
    }
    for (const c of (children || [])) if (c !== null && c !== undefined) e.appendChild(typeof c === 'string' ? document.createTextNode(c) : c);
    return e;
  }
  const isNum = function (v) { return typeof v === 'number' && isFinite(v); };
  function num(v, digits) {
    if (!isNum(v)) return 'n/a';
    const a = Math.abs(v);
    if (a !== 0 && (a < 1e-3 || a >= 1e5)) return v.toExponential(digits === undefined ? 2 : digits - 1);
    return v.toPrecision(digits === undefined ? 3 : digits);
  }
  const ms = function (s) { return isNum(s) ? (s * 1e3).toFixed(s < 0.01 ? 2 : 1) : 'n/a'; };
  function settingsText(p) {
    const nd = p.non_default || {};
    const keys = Object.keys(nd);
    return keys.length ? keys.map(function (k) { return k + '=' + nd[k]; }).join(', ') : '(defaults)';
  }
  function cell(text, cls) { return el('td', cls ? {class: cls, text: text} : {text: text}); }
  function table(headers, rows) {
    const t = el('table');
    t.appendChild(el('tr', {}, headers.map(function (h) { return el('th', {text: h}); })));
    for (const r of rows) t.appendChild(r);
    return t;
  }
  function chart(parent, spec) {
    const box = el('div', {class: 'chart'});
    parent.appendChild(box);
    if (typeof vegaEmbed !== 'function') {
      fail('the charting library (lib/vega-embed.min.js) did not load');
      return;
    }
    spec.$schema = 'https://vega.github.io/schema/vega-lite/v5.json';
    pending.push(vegaEmbed(box, spec, {actions: false, renderer: 'svg'}).then(function () { return 1; },
      function (e) { fail('chart: ' + (e && e.message || e)); return 0; }));
  }

  let R;
  try {
    R = JSON.parse(document.getElementById('softgi-results').textContent);
  } catch (e) {
    fail('results: ' + e.message);
    document.body.dataset.ready = '1';
    return;
  }
  const content = document.getElementById('content');
  const points = R.points || [];
  const st = R.settings || {};

  content.appendChild(el('h1', {text: 'softgi report'}));
  content.appendChild(el('p', {}, [el('code', {text: R.command || ''})]));
  content.appendChild(el('p', {class: 'muted', text: 'softgi ' + (R.softgi_version || '?') + ', ' + (R.date || '') + ', budget ' +
    (R.budget || '?') + ': ' + st.width + (st.height ? 'x' + st.height : ' px wide') + ', frames at t = ' +
    (st.frame_times || []).join(', ') + ' s, median of ' + st.timed_frames + ' timed frames after ' + st.warmup_frames +
    ' warm-up, references to noise ' + st.target_noise + ' (cap ' + st.max_spp + ' spp), path tracer to ' + st.pt_max_spp +
    ' spp, backends ' + (st.backends || []).join(', ') + (st.concurrent_jobs > 1 ? ', ' + st.concurrent_jobs +
    ' jobs side by side (times share the CPU)' : '') + '.'}));
  content.appendChild(el('p', {class: 'note', html: 'Errors are relMSE (&epsilon; = 0.01) over the surface pixels with the ' +
    'reference\'s own noise removed (two independent halves), with 95&nbsp;% intervals; points whose error the reference cannot ' +
    'resolve are drawn hollow and marked <span class="floor">&#9675; below the noise floor</span>. Times are medians of whole ' +
    'frames. docs/reports.md in the softgi source explains every number. All parameters of every point are in ' +
    '<a href="results.json">results.json</a> (also <a href="results.csv">results.csv</a>).'}));
  if ((R.missing_jobs || []).length)
    content.appendChild(el('p', {class: 'floor', text: R.missing_jobs.length + ' of ' + R.planned_jobs +
      ' planned jobs have no result yet: ' + R.missing_jobs.join(', ')}));
  if (!points.length) content.appendChild(el('p', {text: 'No results yet.'}));

  for (const scene of (R.scenes || [])) {
    const sp = points.filter(function (p) { return p.scene === scene.name; });
    const sec = el('section', {id: 'scene-' + scene.name});
    content.appendChild(sec);
    sec.appendChild(el('h2', {text: 'Scene ' + scene.name}));
    sec.appendChild(el('p', {class: 'muted', text: (scene.resolution ? scene.resolution.join('x') + ', ' : '') +
      (scene.surface_pixels || '?') + ' surface pixels, ' + sp.length + ' points' +
      (scene.static ? '; nothing in it moves, so it is measured at one time only' : '')}));
    if (!sp.length) { sec.appendChild(el('p', {text: 'No points for this scene yet.'})); continue; }
    const good = sp.filter(function (p) { return !p.error && isNum(p.seconds) && p.errors && p.errors.final; });
    const frames = Array.from(new Set(sp.map(function (p) { return p.frame_time; }))).sort(function (a, b) { return a - b; });

    // (a) Pareto: error against time, log-log.
    sec.appendChild(el('h3', {text: 'Error against time'}));
    let floorValue = Infinity;
    for (const p of good) {
      const e = p.errors.final;
      for (const v of [e.relmse, e.ci_low]) if (isNum(v) && v > 0) floorValue = Math.min(floorValue, v);
    }
    for (const pt of (scene.path_tracer || [])) for (const c of pt.curve) if (isNum(c.relmse) && c.relmse > 0) floorValue = Math.min(floorValue, c.relmse);
    floorValue = isFinite(floorValue) ? floorValue / 2 : 1e-6;
    const clamp = function (v) { return isNum(v) && v > floorValue ? v : floorValue; };
    for (const t of frames) {
      const rows = good.filter(function (p) { return p.frame_time === t; }).map(function (p) {
        const e = p.errors.final;
        const floor = e.below_noise_floor || !(e.relmse > 0);
        return {id: p.id, technique: p.technique, backend: p.backend, rung: p.rung, ms: p.seconds * 1e3, relmse: clamp(e.relmse),
                lo: clamp(e.ci_low), hi: clamp(e.ci_high), shown: num(e.relmse) + ' [' + num(e.ci_low) + ', ' + num(e.ci_high) + ']',
                ssim: num(e.ssim), flip: num(e.flip), settings: settingsText(p), filled: !floor,
                floor: floor ? 'below the noise floor' : 'resolved', pareto: !!p.pareto};
      });
      const front = rows.filter(function (r) { return r.pareto; }).sort(function (a, b) { return a.ms - b.ms; });
      const curve = [];
      for (const pt of (scene.path_tracer || [])) if (pt.frame_time === t)
        for (const c of pt.curve) if (isNum(c.seconds) && c.seconds > 0) curve.push({ms: c.seconds * 1e3, relmse: clamp(c.relmse), spp: c.spp, series: 'path tracer'});
      const xs = {field: 'ms', type: 'quantitative', scale: {type: 'log'}, title: 'frame time (ms, median)'};
      const ys = {field: 'relmse', type: 'quantitative', scale: {type: 'log'}, title: 'final relMSE (noise removed)'};
      const layers = [];
      if (curve.length) layers.push({data: {values: curve}, mark: {type: 'line', point: {color: '#888'}, color: '#888', strokeDash: [4, 3]},
        encoding: {x: xs, y: ys, tooltip: [{field: 'series'}, {field: 'spp', title: 'spp'}, {field: 'ms', format: '.3f'}, {field: 'relmse', format: '.3e'}]}});
      if (front.length > 1) layers.push({data: {values: front}, mark: {type: 'line', interpolate: 'step-after', color: '#222', opacity: 0.5},
        encoding: {x: xs, y: ys}});
      layers.push({data: {values: rows}, mark: {type: 'rule'}, encoding: {x: xs, y: {field: 'lo', type: 'quantitative', scale: {type: 'log'}},
        y2: {field: 'hi'}, color: {field: 'technique', type: 'nominal'}}});
      layers.push({data: {values: rows}, mark: {type: 'point', size: 90, strokeWidth: 2},
        encoding: {x: xs, y: ys, color: {field: 'technique', type: 'nominal', legend: {title: 'technique'}}, shape: {field: 'backend', type: 'nominal'},
          fill: {condition: {test: 'datum.filled', field: 'technique', type: 'nominal', legend: null}, value: 'white'},
          tooltip: [{field: 'id'}, {field: 'technique'}, {field: 'rung'}, {field: 'ms', title: 'ms', format: '.3f'},
                    {field: 'shown', title: 'relMSE [95% CI]'}, {field: 'floor', title: 'reference'}, {field: 'ssim', title: 'SSIM'},
                    {field: 'flip', title: 'FLIP'}, {field: 'settings', title: 'non-default settings'}, {field: 'pareto', title: 'on the front'}]}});
      if (frames.length > 1) sec.appendChild(el('p', {text: 't = ' + t + ' s'}));
      chart(sec, {width: 640, height: 360, title: scene.name + ', t = ' + t + ' s: Pareto front (solid), path tracer (dashed)',
                  layer: layers, resolve: {scale: {color: 'shared'}}});
    }

    // (b) Per-pass time, stacked.
    sec.appendChild(el('h3', {text: 'Time per pass'}));
    // One chart per technique: each has its own passes, and one legend of every technique's passes
    // would be too long to read (and longer than Vega draws).
    const passTechniques = [];
    for (const p of good) if (passTechniques.indexOf(p.technique) < 0) passTechniques.push(p.technique);
    for (const t of passTechniques) {
      const passRows = [];
      for (const p of good) if (p.technique === t) for (const ps of (p.passes || [])) passRows.push({point: p.id, pass: ps.name, ms: ps.seconds * 1e3});
      if (passRows.length)
        chart(sec, {title: t, width: 640, height: {step: 16}, data: {values: passRows}, mark: 'bar',
          encoding: {y: {field: 'point', type: 'nominal', sort: null, title: null}, x: {field: 'ms', type: 'quantitative', stack: 'zero', title: 'median ms per pass'},
                     color: {field: 'pass', type: 'nominal', sort: null}, tooltip: [{field: 'point'}, {field: 'pass'}, {field: 'ms', format: '.3f'}]}});
    }

    // (c) Equal time.
    sec.appendChild(el('h3', {text: 'Against the path tracer at equal time'}));
    sec.appendChild(el('p', {class: 'muted', text: 'Values marked \u2248 lie beyond the end of the path tracer\'s measured curve: ' +
      'extrapolated with its expected relMSE c / N at N samples per pixel (an unbiased estimator; c and the time per sample ' +
      'from the curve\'s last step).'}));
    sec.appendChild(table(['point', 'time (ms)', 'relMSE', 'path tracer relMSE at that time', 'path tracer time to match (ms)', 'speed-up'],
      good.map(function (p) {
        const q = p.equal_time || {};
        const x = q.extrapolated || {};
        const approx = function (flag, text) { return flag ? '\u2248 ' + text : text; };
        const match = isNum(q.pt_seconds_to_match) ? approx(x.pt_seconds_to_match, ms(q.pt_seconds_to_match))
                      : (isNum(q.pt_max_seconds) ? '> ' + ms(q.pt_max_seconds) : 'n/a');
        const speed = isNum(q.pt_seconds_to_match) && p.seconds > 0 ? approx(x.pt_seconds_to_match, num(q.pt_seconds_to_match / p.seconds) + 'x') : 'n/a';
        return el('tr', {}, [cell(p.id), cell(ms(p.seconds), 'num'), cell(num(p.errors.final.relmse), 'num'),
                             cell(isNum(q.pt_relmse_at_same_time) ? approx(x.pt_relmse_at_same_time, num(q.pt_relmse_at_same_time)) : 'n/a', 'num'),
                             cell(match, 'num'), cell(speed, 'num')]);
      })));

    // (d) Error budget.
    sec.appendChild(el('h3', {text: 'Error budget'}));
    sec.appendChild(el('p', {class: 'muted', text: 'Each source on its own, as a noise-corrected relMSE. Proxy geometry: the proxy ' +
      'spheres alone as blockers (objects without proxies shadow and reflect nothing, as for a sphere-proxy technique) against ' +
      'the real geometry; none for techniques that shadow with the scene\'s own geometry. SH truncation: the order-n SH light ' +
      'against the full environment. Approximation: the technique against the reference of its own blockers and order-n SH ' +
      'light. Resolution: the technique against itself at full receiver resolution. Errors of different signs cancel, so the ' +
      'entries need not add up to the total.'}));
    const sources = [['proxy_geometry', 'proxy geometry'], ['sh_truncation', 'SH truncation'], ['approximation', 'approximation'], ['resolution', 'resolution']];
    sec.appendChild(table(['point'].concat(sources.map(function (s) { return s[1]; }), ['total']), good.map(function (p) {
      const b = p.budget || {};
      return el('tr', {}, [cell(p.id)].concat(sources.map(function (s) { return cell(num(b[s[0]]), 'num'); }), [cell(num(b.total), 'num')]));
    })));
    const budgetRows = [];
    for (const p of good) for (const s of sources) if (isNum((p.budget || {})[s[0]])) budgetRows.push({point: p.id, source: s[1], relmse: p.budget[s[0]]});
    if (budgetRows.length)
      chart(sec, {width: 640, height: {step: 10}, data: {values: budgetRows}, mark: 'bar',
        encoding: {y: {field: 'point', type: 'nominal', sort: null, title: null}, yOffset: {field: 'source'},
                   x: {field: 'relmse', type: 'quantitative', title: 'relMSE of each source'}, color: {field: 'source', type: 'nominal'},
                   tooltip: [{field: 'point'}, {field: 'source'}, {field: 'relmse', format: '.3e'}]}});

    // (e) Images against the reference, with the FLIP map.
    sec.appendChild(el('h3', {text: 'Images'}));
    const withImages = good.filter(function (p) { return p.images && p.images.final; });
    if (withImages.length) {
      const select = el('select', {'aria-label': 'point'}, withImages.map(function (p) { return el('option', {value: p.id, text: p.id}); }));
      const slider = el('input', {type: 'range', min: '0', max: '100', value: '50', 'aria-label': 'reference share'});
      const base = el('img', {alt: 'technique'}), top = el('img', {class: 'top', alt: 'reference'}), flip = el('img', {alt: 'FLIP map'});
      const caption = el('p', {class: 'muted'});
      const apply = function () { top.style.clipPath = 'inset(0 0 0 ' + slider.value + '%)'; };
      const show = function () {
        const p = withImages.find(function (x) { return x.id === select.value; });
        base.src = p.images.final;
        top.src = p.images.reference || p.images.final;
        if (p.images.flip_map) flip.src = p.images.flip_map; else flip.removeAttribute('src');
        caption.textContent = 'left of the line: ' + p.id + ' (' + settingsText(p) + '); right: the reference. FLIP ' +
          num(p.errors.final.flip) + ', relMSE ' + num(p.errors.final.relmse);
        apply();
      };
      select.addEventListener('change', show);
      slider.addEventListener('input', apply);
      sec.appendChild(el('p', {}, [select, ' technique ', slider, ' reference']));
      sec.appendChild(el('div', {class: 'viewer'}, [el('div', {class: 'compare'}, [base, top]),
        el('div', {class: 'flip'}, [flip, el('div', {class: 'colorbar'}), el('div', {class: 'ticks'}, [el('span', {text: '0'}),
          el('span', {text: '0.5'}), el('span', {text: '1'})]), el('div', {class: 'muted', text: 'FLIP error (HDR-FLIP against the reference)'})])]));
      sec.appendChild(caption);
      show();
    }

    // (f) Every point.
    sec.appendChild(el('h3', {text: 'Every point'}));
    sec.appendChild(table(['id', 'technique', 'backend', 'rung', 't (s)', 'time (ms)', 'relMSE [95% CI]', 'SSIM', 'FLIP', 'non-default settings', 'command'],
      sp.map(function (p) {
        if (p.error) return el('tr', {class: 'failed'}, [cell(p.id), cell(p.technique), cell(p.backend), cell(String(p.rung)), cell(String(p.frame_time)),
          el('td', {colspan: '6', text: 'failed: ' + p.error})]);
        const e = p.errors.final;
        const rel = el('td', {class: 'num'}, [num(e.relmse) + ' [' + num(e.ci_low) + ', ' + num(e.ci_high) + ']' + (e.below_noise_floor ? ' ' : '')]);
        if (e.below_noise_floor) rel.appendChild(el('span', {class: 'floor', title: 'below the reference\'s noise floor', text: '\u25cb'}));
        return el('tr', {}, [cell(p.id), cell(p.technique), cell(p.backend), cell(p.rung + '/' + (p.rungs - 1)), cell(String(p.frame_time)),
          cell(ms(p.seconds) + ' (' + ms(p.seconds_min) + '\u2013' + ms(p.seconds_max) + ')', 'num'), rel, cell(num(e.ssim), 'num'),
          cell(num(e.flip), 'num'), cell(settingsText(p)), el('td', {class: 'mono', text: p.command || ''})]);
      })));

    // References.
    sec.appendChild(el('h3', {text: 'References'}));
    sec.appendChild(table(['t (s)', 'key', 'what', 'spp', 'noise', 'converged', 'seconds', 'image'], (scene.references || []).map(function (r) {
      return el('tr', {}, [cell(String(r.frame_time)), cell(r.key), cell(r.label || ''), cell(String(r.spp), 'num'), cell(num(r.noise), 'num'),
        cell(r.converged ? 'yes' : 'no (cap reached)'), cell(num(r.seconds), 'num'), el('td', {}, [el('a', {href: r.image, text: 'png'})])]);
    })));
  }

  // The comparative benchmark suite (bench_techniques' JSON given with --bench-json).
  if (R.bench && (R.bench.rows || []).length) {
    const B = R.bench, ctx = B.context || {};
    const sec = el('section', {id: 'bench'});
    content.appendChild(sec);
    sec.appendChild(el('h2', {text: 'Benchmark suite (bench_techniques)'}));
    sec.appendChild(el('p', {class: 'muted', text: 'Every technique at default settings on each scene and backend, ' +
      'time per frame as Google Benchmark reports it (the mean of a run\'s frames; the median over repetitions where repeated), ' +
      'from ' + (ctx.host_name || '?') + ', ' + (ctx.num_cpus || '?') + ' CPUs at ' + (ctx.mhz_per_cpu || '?') + ' MHz, ' +
      (ctx.date || '') + ' (' + (ctx.library_build_type || '?') + ' benchmark library). Raw: '}, [el('a', {href: B.source, text: B.source})]));
    const ok = B.rows.filter(function (r) { return isNum(r.ms); });
    if (ok.length)
      chart(sec, {width: 420, data: {values: ok.map(function (r) { return {scene: r.scene + ' (' + r.backend + ')', technique: r.technique, ms: r.ms}; })},
        // A dot plot: the times span orders of magnitude (log axis), which bars cannot start from.
        mark: {type: 'point', filled: true, size: 90}, encoding: {
          y: {field: 'scene', type: 'nominal', title: null},
          x: {field: 'ms', type: 'quantitative', scale: {type: 'log'}, title: 'ms per frame (log)'},
          color: {field: 'technique', type: 'nominal'}, shape: {field: 'technique', type: 'nominal'},
          tooltip: [{field: 'scene'}, {field: 'technique'}, {field: 'ms', format: '.3g'}]}});
    sec.appendChild(table(['scene', 'backend', 'technique', 'ms per frame', '× fastest', 'slowest passes (mean ms)', 'upload MB', 'download MB', 'pruned'],
      B.rows.map(function (r) {
        if (!isNum(r.ms)) return el('tr', {}, [cell(r.scene), cell(r.backend), cell(r.technique), cell('failed: ' + (r.error || '?'))]);
        const passes = Object.keys(r.passes || {}).map(function (k) { return [k, r.passes[k]]; })
          .sort(function (a, b) { return b[1] - a[1]; }).slice(0, 3).map(function (x) { return x[0] + ' ' + num(x[1]); }).join(', ');
        return el('tr', {}, [cell(r.scene), cell(r.backend), cell(r.technique), cell(num(r.ms), 'num'), cell(num(r.x_fastest), 'num'),
          cell(passes), cell(num(r.upload_MB), 'num'), cell(num(r.download_MB), 'num'), cell(String(r.pruned_passes === undefined ? '' : r.pruned_passes), 'num')]);
      })));
  }

  Promise.all(pending).then(function (drawn) {
    document.body.dataset.charts = String(drawn.reduce(function (a, b) { return a + b; }, 0));
    document.body.dataset.ready = '1';
  });
})();
</script>
</body>
</html>
)HTML";

// RFC 4180: quoted when it holds a comma, a quote or a line break; quotes doubled.
std::string csv_field(const std::string& s) {
  if (s.find_first_of(",\"\r\n") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}

std::string csv_value(const Json& v) {
  if (v.is_null()) return "";
  if (v.is_string()) return csv_field(v.get<std::string>());
  if (v.is_boolean()) return v.get<bool>() ? "true" : "false";
  if (v.is_number_float()) {
    std::ostringstream os;
    os.precision(9);
    os << v.get<double>();
    return os.str();
  }
  return csv_field(v.dump());
}

// results[a][b]... or null where any step is missing.
const Json& at_path(const Json& j, std::initializer_list<const char*> path) {
  static const Json null_value;
  const Json* cur = &j;
  for (const char* k : path) {
    if (!cur->is_object() || !cur->contains(k)) return null_value;
    cur = &(*cur)[k];
  }
  return *cur;
}

}  // namespace

std::string page_html(const Json& results) { return std::string(kHead) + embeddable(results) + kScript; }

std::string csv_table(const Json& results) {
  std::ostringstream out;
  const char* const components[] = {"final", "direct", "indirect"};
  const char* const fields[] = {"relmse", "relmse_raw", "noise", "ci_low", "ci_high", "below_noise_floor", "ssim", "flip"};
  out << "id,scene,technique,backend,rung,rungs,frame_time,seconds,seconds_min,seconds_max";
  for (const char* c : components)
    for (const char* f : fields) out << "," << c << "_" << f;
  out << ",budget_proxy_geometry,budget_sh_truncation,budget_approximation,budget_resolution,pt_relmse_at_same_time,"
         "pt_seconds_to_match,pt_relmse_at_same_time_extrapolated,pt_seconds_to_match_extrapolated,pareto,non_default,command,"
         "error\r\n";
  for (const Json& p : at_path(results, {"points"})) {
    for (const char* k : {"id", "scene", "technique", "backend", "rung", "rungs", "frame_time", "seconds", "seconds_min", "seconds_max"})
      out << (std::string(k) == "id" ? "" : ",") << csv_value(at_path(p, {k}));
    for (const char* c : components)
      for (const char* f : fields) out << "," << csv_value(at_path(p, {"errors", c, f}));
    for (const char* b : {"proxy_geometry", "sh_truncation", "approximation", "resolution"}) out << "," << csv_value(at_path(p, {"budget", b}));
    out << "," << csv_value(at_path(p, {"equal_time", "pt_relmse_at_same_time"})) << ","
        << csv_value(at_path(p, {"equal_time", "pt_seconds_to_match"})) << ","
        << csv_value(at_path(p, {"equal_time", "extrapolated", "pt_relmse_at_same_time"})) << ","
        << csv_value(at_path(p, {"equal_time", "extrapolated", "pt_seconds_to_match"})) << "," << csv_value(at_path(p, {"pareto"}));
    std::string nd;
    const Json& non_default = at_path(p, {"non_default"});
    if (non_default.is_object())
      for (const auto& [k, v] : non_default.items()) nd += (nd.empty() ? "" : ";") + k + "=" + (v.is_string() ? v.get<std::string>() : v.dump());
    out << "," << csv_field(nd) << "," << csv_value(at_path(p, {"command"})) << "," << csv_value(at_path(p, {"error"})) << "\r\n";
  }
  return out.str();
}

const std::vector<std::string>& page_libraries() {
  static const std::vector<std::string> files = {"vega.min.js",  "vega-lite.min.js",  "vega-embed.min.js",
                                                 "vega.LICENSE", "vega-lite.LICENSE", "vega-embed.LICENSE"};
  return files;
}

}  // namespace softgi::app::report
