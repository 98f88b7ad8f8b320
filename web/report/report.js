// The ddhgs report page: builds tables, charts (uPlot), the 3D view
// (assets/splat_view.js) and the spectral viewer from window.DDHGS_REPORT
// (assets/data.js) and the per-view band atlases in window.DDHGS_VIEWER_DATA
// (assets/viewer/*.js). Data arrive as <script src> files because a page
// opened from disk cannot fetch() files.
"use strict";

(function () {
  const R = window.DDHGS_REPORT;
  const $ = (id) => document.getElementById(id);

  function el(tag, attrs, children) {
    const node = document.createElement(tag);
    for (const [k, v] of Object.entries(attrs || {})) {
      if (k === "text") node.textContent = v;
      else node.setAttribute(k, v);
    }
    for (const c of children || []) node.appendChild(c);
    return node;
  }

  function fmt(value, digits) {
    if (value === null || value === undefined) return "–";
    if (typeof value !== "number") return String(value);
    return Number.isInteger(value) ? String(value) : value.toFixed(digits);
  }

  function table(headers, rows) {
    const head = el("tr", {}, headers.map((h) => el("th", { text: h })));
    const body = rows.map((r) => el("tr", {}, r.map((c) => el("td", { text: c }))));
    return el("table", {}, [el("thead", {}, [head]), el("tbody", {}, body)]);
  }

  function keyValueTable(obj) {
    return table(
      ["key", "value"],
      Object.entries(obj).map(([k, v]) => [k, typeof v === "object" ? JSON.stringify(v) : fmt(v, 4)])
    );
  }

  const kColours = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e"];

  // A line chart; series: [{label, values, pointsOnly}], nulls leave gaps.
  function chart(parent, title, xLabel, yLabel, x, series, opts) {
    const options = Object.assign(
      {
        title: title,
        width: 370,
        height: 240,
        scales: { x: { time: false } },
        axes: [{ label: xLabel }, { label: yLabel }],
        series: [{ label: xLabel }].concat(
          series.map((s, i) => ({
            label: s.label,
            stroke: kColours[i % kColours.length],
            width: 1.5,
            paths: s.pointsOnly ? () => null : undefined,
            points: { show: s.pointsOnly || x.length < 40, size: s.pointsOnly ? 8 : 5 },
          }))
        ),
      },
      opts || {}
    );
    const box = el("div", { class: "chart" });
    parent.appendChild(box);
    return new uPlot(options, [x].concat(series.map((s) => s.values)), box);
  }

  function metricsSection() {
    const rows = R.metrics.map((m) => [
      m.label,
      fmt(m.psnr, 2),
      fmt(m.ssim, 4),
      fmt(m.sam, 4),
      fmt(m.rmse, 4),
    ]);
    $("metrics").appendChild(table(["prediction vs ground truth", "PSNR dB", "SSIM", "SAM rad", "RMSE"], rows));
    $("metrics").appendChild(el("p", { class: "note", text: R.metrics_note }));
  }

  function curvesSection() {
    const c = R.curves;
    const box = $("curves");
    if (!c.iter.length) {
      box.appendChild(el("p", { class: "note", text: "metrics.jsonl is missing or empty." }));
      return;
    }
    chart(box, "Training loss", "iteration", "loss", c.iter, [{ label: "loss", values: c.loss }]);
    chart(box, "Training-view PSNR", "iteration", "PSNR dB", c.iter, [
      { label: "train PSNR", values: c.train_psnr },
    ]);
    chart(box, "Gaussian count", "iteration", "Gaussians", c.iter, [
      { label: "Gaussians", values: c.num_gaussians },
    ]);
    // Time to quality: the test views' PSNR as training went (output.test_every).
    const t = c.test;
    if (t && t.minutes.length) {
      const series = [{ label: "test PSNR (captured)", values: t.test_psnr }];
      if (t.test_psnr_clean.some((v) => v !== null))
        series.push({ label: "test PSNR (clean truth)", values: t.test_psnr_clean });
      chart(box, "Test-view PSNR against training time", "minutes of training", "PSNR dB", t.minutes, series);
    }
  }

  function spectralSection() {
    const box = $("spectral");
    const wl = R.wavelengths_nm;
    chart(box, "Per-band PSNR (mean over views)", "wavelength nm", "PSNR dB", wl, R.per_band.psnr);
    chart(box, "Per-band RMSE (mean over views)", "wavelength nm", "RMSE", wl, R.per_band.rmse);
    const names = R.sam_per_view.views;
    const idx = names.map((_, i) => i);
    const series = R.sam_per_view.series.map((s) => Object.assign({ pointsOnly: true }, s));
    chart(box, "SAM per view (mean over pixels)", "view", "SAM rad", idx, series, {
      scales: { x: { time: false, range: [-0.5, names.length - 0.5] } },
      axes: [
        {
          label: "view",
          splits: () => idx,
          values: (u, ticks) => ticks.map((t) => names[t] || ""),
        },
        { label: "SAM rad" },
      ],
    });
  }

  function figuresSection() {
    const f = R.figures;
    const select = $("figure-range");
    for (const sel of f.selections) select.appendChild(el("option", { value: sel.label, text: sel.title }));
    const grid = $("figure-grid");
    if (f.views.length === 0) {
      grid.appendChild(el("p", { class: "note", text: R.views_note || "No test view to show." }));
      return;
    }
    function show() {
      grid.replaceChildren();
      for (const v of f.views) {
        grid.appendChild(
          el("figure", {}, [
            el("img", { src: v.files[select.value], alt: v.name + " " + select.value }),
            el("figcaption", { text: v.name + ": " + f.caption }),
          ])
        );
      }
    }
    select.addEventListener("change", show);
    show();
  }

  // A georeferenced run: its orthomosaic and NDVI map, with GSD and CRS.
  function orthoSection() {
    const o = R.ortho;
    if (!o) return;
    $("sec-ortho").hidden = false;
    $("nav-ortho").hidden = false;
    const grid = $("ortho-grid");
    for (const f of o.files) {
      grid.appendChild(
        el("figure", {}, [el("img", { src: f.src, alt: f.title }), el("figcaption", { text: f.title })])
      );
    }
    $("ortho-note").textContent = o.caption;
  }

  // Band atlases decoded once into byte arrays: value of band b at (x, y).
  function decodeAtlas(uri, meta) {
    return new Promise((resolve, reject) => {
      const img = new Image();
      img.onload = () => {
        const canvas = el("canvas", { width: img.width, height: img.height });
        const ctx = canvas.getContext("2d");
        ctx.drawImage(img, 0, 0);
        const rgba = ctx.getImageData(0, 0, img.width, img.height).data;
        resolve((b, x, y) => {
          const col = b % meta.cols;
          const row = Math.floor(b / meta.cols);
          const px = col * meta.width + x;
          const py = row * meta.height + y;
          return rgba[4 * (py * img.width + px)] / 255;
        });
      };
      img.onerror = () => reject(new Error("cannot decode band atlas of " + meta.name));
      img.src = uri;
    });
  }

  function viewerSection() {
    const V = R.viewer;
    if (V.views.length === 0) {
      $("spectrum-label").textContent = R.views_note || "No test view to show.";
      return Promise.resolve();
    }
    const wl = R.wavelengths_nm;
    const slider = $("band-slider");
    const viewSelect = $("viewer-view");
    const canvases = { truth: $("canvas-truth"), render: $("canvas-render"), diff: $("canvas-diff") };
    const truthSelect = $("viewer-truth");
    slider.max = String(wl.length - 1);
    slider.value = String(Math.floor((wl.length - 1) / 2));
    V.views.forEach((v, i) => viewSelect.appendChild(el("option", { value: String(i), text: v.name })));
    const state = { view: null, sources: null, pixel: null, bandsShown: 0, spectraPlotted: 0 };
    window.ddhgsViewer = state;

    const spectrumBox = $("spectrum");
    const spectrum = chart(
      spectrumBox,
      "Spectrum at the clicked pixel",
      "wavelength nm",
      "reflectance",
      wl,
      V.sources.map((s) => ({ label: s.title, values: wl.map(() => null) })),
      { width: 560, height: 300, scales: { x: { time: false }, y: { range: [0, 1] } } }
    );
    state.spectrumChart = spectrum;

    function drawBand() {
      const meta = state.view;
      const band = Number(slider.value);
      $("band-label").textContent = "band " + band + ": " + wl[band].toFixed(1) + " nm";
      const truth = state.sources[truthSelect.value];
      const render = state.sources.render;
      const lut = R.viridis;
      for (const [name, canvas] of Object.entries(canvases)) {
        canvas.width = meta.width;
        canvas.height = meta.height;
        const ctx = canvas.getContext("2d");
        const img = ctx.createImageData(meta.width, meta.height);
        for (let y = 0; y < meta.height; ++y) {
          for (let x = 0; x < meta.width; ++x) {
            const o = 4 * (y * meta.width + x);
            if (name === "diff") {
              const e = Math.abs(render(band, x, y) - truth(band, x, y)) / R.diff_max;
              const c = lut[Math.min(255, Math.round(255 * e))];
              img.data[o] = c[0];
              img.data[o + 1] = c[1];
              img.data[o + 2] = c[2];
            } else {
              const g = Math.round(255 * (name === "truth" ? truth : render)(band, x, y));
              img.data[o] = img.data[o + 1] = img.data[o + 2] = g;
            }
            img.data[o + 3] = 255;
          }
        }
        ctx.putImageData(img, 0, 0);
        if (state.pixel) {
          // A ring around the clicked pixel, about 3% of the image wide.
          const r = Math.max(2, Math.round(meta.width / 32));
          ctx.strokeStyle = "#ff2d2d";
          ctx.lineWidth = Math.max(1, r / 3);
          const [px, py] = state.pixel;
          ctx.strokeRect(px - r + 0.5, py - r + 0.5, 2 * r, 2 * r);
        }
      }
      state.bandsShown += 1;
    }

    function plotSpectrum() {
      const [x, y] = state.pixel;
      const data = [wl].concat(V.sources.map((s) => wl.map((_, b) => state.sources[s.key](b, x, y))));
      spectrum.setData(data);
      $("spectrum-label").textContent =
        state.view.name + ", pixel (" + x + ", " + y + ") of " + state.view.width + " x " + state.view.height;
      state.spectraPlotted += 1;
    }

    async function selectView() {
      const meta = V.views[Number(viewSelect.value)];
      const data = window.DDHGS_VIEWER_DATA[meta.name];
      const sources = {};
      for (const s of V.sources) sources[s.key] = await decodeAtlas(data[s.key], meta);
      state.view = meta;
      state.sources = sources;
      state.pixel = null;
      drawBand();
    }

    for (const s of V.sources.filter((s) => s.key !== "render"))
      truthSelect.appendChild(el("option", { value: s.key, text: s.title }));
    slider.addEventListener("input", drawBand);
    truthSelect.addEventListener("change", drawBand);
    viewSelect.addEventListener("change", selectView);
    for (const canvas of Object.values(canvases)) {
      canvas.addEventListener("click", (event) => {
        const rect = canvas.getBoundingClientRect();
        const x = Math.floor(((event.clientX - rect.left) / rect.width) * state.view.width);
        const y = Math.floor(((event.clientY - rect.top) / rect.height) * state.view.height);
        state.pixel = [Math.min(x, state.view.width - 1), Math.min(y, state.view.height - 1)];
        plotSpectrum();
        drawBand();
      });
    }
    return selectView();
  }

  // The 3D view (assets/splat_view.js); a browser without WebGL 2 gets a note
  // instead, and the rest of the report still works.
  function splatSection() {
    try {
      window.ddhgsSplatView(R, window.DDHGS_SPLATS, { el: el, chart: chart });
    } catch (e) {
      $("splat-note").textContent = "The 3D view needs WebGL 2, which this browser did not provide (" + e.message + ").";
    }
  }

  function summarySection() {
    $("data-summary").appendChild(keyValueTable(R.data_summary));
    if (R.train_summary) $("train-summary").appendChild(keyValueTable(R.train_summary));
    else $("train-summary").appendChild(el("p", { class: "note", text: "train_summary.json is missing." }));
    $("config").textContent = JSON.stringify(R.config, null, 2);
  }

  async function main() {
    document.title = R.title;
    $("title").textContent = R.title;
    $("subtitle").textContent = R.subtitle;
    metricsSection();
    curvesSection();
    spectralSection();
    figuresSection();
    orthoSection();
    summarySection();
    splatSection();
    await viewerSection();
    window.ddhgsReady = true;
  }

  main().catch((e) => {
    console.error(e);
    document.body.prepend(el("p", { class: "error", text: "report error: " + e.message }));
  });
})();
