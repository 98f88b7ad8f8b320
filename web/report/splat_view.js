// The report's 3D spectral view: the trained Gaussians drawn by the
// PlayCanvas engine's Gaussian-splat renderer (assets/playcanvas.min.js),
// recoloured per band on the GPU, with training cameras as frustums and a
// click that plots the spectrum of the Gaussians under the cursor.
//
// Data: window.DDHGS_SPLATS (assets/splats.js, see src/eval/report_splats.h).
// Every band value of a Gaussian is mean + sum_k c_k vector_k with K <= 16
// 8-bit coefficients c_k; a band, a band range's mean and pseudo-RGB are
// linear in the band values, so a recolour only changes K weight vectors
// (uniforms) of the shader hook below: the model stays on the GPU as it is.
"use strict";

window.ddhgsSplatView = function (R, S, helpers) {
  const $ = (id) => document.getElementById(id);
  const wl = R.wavelengths_nm;
  const N = wl.length;
  const G = S.count;
  const B = S.basis;
  const K = B.vectors.length;
  const LAYERS = Math.ceil(K / 4);
  const TEX_W = Math.min(G, 2048);
  const TEX_ROWS = Math.ceil(G / TEX_W);
  const state = { frames: 0, recolours: 0, picks: 0, pick: null, ready: false };
  window.ddhgsSplats = state;

  function bytes(b64) {
    const s = atob(b64);
    const out = new Uint8Array(s.length);
    for (let i = 0; i < s.length; ++i) out[i] = s.charCodeAt(i);
    return out;
  }

  // The Gaussians in scene units: centres, log scales, unit quaternions
  // (w, x, y, z), opacities 0-1, and their 8-bit basis coefficients.
  const means = new Float32Array(bytes(S.means).buffer);
  const scaleSteps = new Uint16Array(bytes(S.log_scales).buffer);
  const quatSteps = new Int8Array(bytes(S.quats).buffer);
  const opacitySteps = bytes(S.opacity);
  const coefficients = bytes(B.coefficients);
  const [scaleLow, scaleHigh] = S.log_scale_range;
  const logScale = (i) => scaleLow + (scaleSteps[i] / 65535) * (scaleHigh - scaleLow);

  // Band values of Gaussian g: [N].
  function spectrumOf(g, out) {
    for (let n = 0; n < N; ++n) out[n] = B.mean[n];
    for (let k = 0; k < K; ++k) {
      const c = B.low[k] + (coefficients[g * K + k] / 255) * (B.high[k] - B.low[k]);
      for (let n = 0; n < N; ++n) out[n] += c * B.vectors[k][n];
    }
    return out;
  }

  // ---- the PlayCanvas scene ----
  const canvas = $("splat-canvas");
  const start = S.start;
  canvas.width = 640;
  canvas.height = Math.round((640 * start.height) / start.width);
  const app = new pc.Application(canvas, {
    graphicsDeviceOptions: { antialias: false, preserveDrawingBuffer: true },
  });
  app.setCanvasFillMode(pc.FILLMODE_NONE);
  app.setCanvasResolution(pc.RESOLUTION_FIXED, canvas.width, canvas.height);

  const names = ["x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1", "scale_2",
    "rot_0", "rot_1", "rot_2", "rot_3"];
  const columns = {};
  for (const name of names) columns[name] = new Float32Array(G);
  for (let i = 0; i < G; ++i) {
    for (let a = 0; a < 3; ++a) {
      columns["xyz"[a]][i] = means[3 * i + a];
      columns["scale_" + a][i] = logScale(3 * i + a);
    }
    for (let a = 0; a < 4; ++a) columns["rot_" + a][i] = quatSteps[4 * i + a] / 127;
    const o = Math.min(Math.max((opacitySteps[i] + 0.5) / 256, 1e-4), 1 - 1e-4);
    columns.opacity[i] = Math.log(o / (1 - o));
  }
  const data = new pc.GSplatData([
    { name: "vertex", count: G, properties: names.map((n) => ({ type: "float", name: n, storage: columns[n], byteSize: 4 })) },
  ]);
  const splat = new pc.Entity("splats");
  splat.addComponent("gsplat", { unified: false, resource: new pc.GSplatResource(app.graphicsDevice, data) });
  app.root.addChild(splat);

  // Coefficients as RGBA8 texels: 4 per texel, LAYERS texel rows-blocks per splat.
  const texels = new Uint8Array(TEX_W * TEX_ROWS * LAYERS * 4);
  for (let i = 0; i < G; ++i)
    for (let k = 0; k < K; ++k) {
      const layer = k >> 2;
      const texel = (layer * TEX_ROWS + Math.floor(i / TEX_W)) * TEX_W + (i % TEX_W);
      texels[4 * texel + (k & 3)] = coefficients[i * K + k];
    }
  const texture = (width, height, levels) =>
    new pc.Texture(app.graphicsDevice, {
      width, height, format: pc.PIXELFORMAT_RGBA8, mipmaps: false, levels: [levels],
      minFilter: pc.FILTER_NEAREST, magFilter: pc.FILTER_NEAREST,
      addressU: pc.ADDRESS_CLAMP_TO_EDGE, addressV: pc.ADDRESS_CLAMP_TO_EDGE,
    });
  const lut = new Uint8Array(256 * 4);
  const material = splat.gsplat.material;
  material.getShaderChunks("glsl").set("gsplatModifyVS", `
uniform sampler2D uCoefficients;
uniform sampler2D uColourMap;
uniform vec3 uWeights[${4 * LAYERS}];
uniform vec3 uOffset;
uniform int uMode;  // 0: linear light -> sRGB, 1: display RGB, 2: channel 0 through the colour map,
                    // 3: (c0 - c1) / (c0 + c1) from -1..1 through the colour map (grey without signal)
void modifySplatCenter(inout vec3 center) {}
void modifySplatRotationScale(vec3 originalCenter, vec3 modifiedCenter, inout vec4 rotation, inout vec3 scale) {}
void modifySplatColor(vec3 center, inout vec4 color) {
  int i = int(splat.index);
  ivec2 uv = ivec2(i % ${TEX_W}, i / ${TEX_W});
  vec3 c = uOffset;
  for (int layer = 0; layer < ${LAYERS}; ++layer) {
    vec4 q = texelFetch(uCoefficients, uv + ivec2(0, layer * ${TEX_ROWS}), 0);
    c += q.x * uWeights[4 * layer] + q.y * uWeights[4 * layer + 1] + q.z * uWeights[4 * layer + 2] + q.w * uWeights[4 * layer + 3];
  }
  if (uMode == 0) {
    vec3 x = clamp(c, 0.0, 1.0);
    color.rgb = mix(12.92 * x, 1.055 * pow(x, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), x));
  } else if (uMode == 1) {
    color.rgb = clamp(c, 0.0, 1.0);
  } else if (uMode == 3) {
    float sum = c.x + c.y;
    float v = 0.5 * ((c.x - c.y) / max(sum, 1e-6) + 1.0);
    color.rgb = sum > 1e-3 ? texture(uColourMap, vec2(clamp(v, 0.0, 1.0) * (255.0 / 256.0) + 0.5 / 256.0, 0.5)).rgb
                           : vec3(0.5);
  } else {
    color.rgb = texture(uColourMap, vec2(clamp(c.x, 0.0, 1.0) * (255.0 / 256.0) + 0.5 / 256.0, 0.5)).rgb;
  }
}`);
  material.setParameter("uCoefficients", texture(TEX_W, TEX_ROWS * LAYERS, texels));
  const colourMap = texture(256, 1, lut);
  material.setParameter("uColourMap", colourMap);
  material.update();

  // ---- camera and orbit controls ----
  const V = (a) => new pc.Vec3(a[0], a[1], a[2]);
  const axis = (cam, row) => new pc.Vec3(cam.rotation[3 * row], cam.rotation[3 * row + 1], cam.rotation[3 * row + 2]);
  // World up: the training cameras' mean "image up" (OpenCV y points down).
  const up = new pc.Vec3();
  for (const cam of S.cameras.length ? S.cameras : [start]) up.sub(axis(cam, 1));
  up.normalize();
  const e1 = new pc.Vec3().cross(up, Math.abs(up.x) < 0.9 ? pc.Vec3.RIGHT : pc.Vec3.FORWARD).normalize();
  const e2 = new pc.Vec3().cross(up, e1);
  const centroid = new pc.Vec3();
  for (let i = 0; i < G; ++i) centroid.add(new pc.Vec3(means[3 * i], means[3 * i + 1], means[3 * i + 2]));
  centroid.mulScalar(1 / G);
  const startPos = V(start.center);
  const forward = axis(start, 2);
  const depth = Math.max(new pc.Vec3().sub2(centroid, startPos).dot(forward), 1e-3);
  const orbit = { target: startPos.clone().add(forward.clone().mulScalar(depth)), radius: depth };
  const offset = new pc.Vec3().sub2(startPos, orbit.target).mulScalar(1 / depth);
  orbit.pitch = Math.asin(Math.max(-1, Math.min(1, offset.dot(up))));
  orbit.yaw = Math.atan2(offset.dot(e2), offset.dot(e1));

  const camera = new pc.Entity("camera");
  camera.addComponent("camera", {
    fov: (2 * Math.atan(start.height / (2 * start.fy)) * 180) / Math.PI,
    nearClip: depth * 0.01, farClip: depth * 100,
  });
  app.root.addChild(camera);
  function placeCamera() {
    const c = Math.cos(orbit.pitch);
    const dir = e1.clone().mulScalar(c * Math.cos(orbit.yaw))
      .add(e2.clone().mulScalar(c * Math.sin(orbit.yaw))).add(up.clone().mulScalar(Math.sin(orbit.pitch)));
    camera.setPosition(orbit.target.clone().add(dir.mulScalar(orbit.radius)));
    camera.lookAt(orbit.target, up);
  }
  placeCamera();

  let drag = null;
  canvas.addEventListener("contextmenu", (e) => e.preventDefault());
  canvas.addEventListener("mousedown", (e) => { drag = { x: e.clientX, y: e.clientY, moved: 0, pan: e.button !== 0 || e.shiftKey }; });
  window.addEventListener("mouseup", (e) => {
    if (drag && drag.moved < 3 && e.target === canvas) pickAt(e);
    drag = null;
  });
  window.addEventListener("mousemove", (e) => {
    if (!drag) return;
    const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
    drag.x = e.clientX; drag.y = e.clientY; drag.moved += Math.abs(dx) + Math.abs(dy);
    if (drag.pan) {
      const s = (2 * orbit.radius * Math.tan((camera.camera.fov * Math.PI) / 360)) / canvas.clientHeight;
      orbit.target.add(camera.right.clone().mulScalar(-dx * s)).add(camera.up.clone().mulScalar(dy * s));
    } else {
      orbit.yaw -= dx * 0.01;
      orbit.pitch = Math.max(-1.5, Math.min(1.5, orbit.pitch + dy * 0.01));
    }
    placeCamera();
  });
  canvas.addEventListener("wheel", (e) => {
    e.preventDefault();
    orbit.radius *= Math.exp(e.deltaY * 0.001);
    placeCamera();
  }, { passive: false });

  // ---- training cameras as frustums ----
  const frustumDepth = 0.15 * depth;
  const lines = [], lineColours = [];
  function frustum(cam, rgba) {
    const c = V(cam.center);
    const corners = [[0, 0], [cam.width, 0], [cam.width, cam.height], [0, cam.height]].map(([u, v]) => {
      const x = (u - cam.cx) / cam.fx, y = (v - cam.cy) / cam.fy;
      return c.clone().add(axis(cam, 0).mulScalar(x * frustumDepth))
        .add(axis(cam, 1).mulScalar(y * frustumDepth)).add(axis(cam, 2).mulScalar(frustumDepth));
    });
    for (let j = 0; j < 4; ++j)
      for (const [a, b] of [[c, corners[j]], [corners[j], corners[(j + 1) % 4]]]) {
        lines.push(a.x, a.y, a.z, b.x, b.y, b.z);
        lineColours.push(...rgba, ...rgba);
      }
  }
  for (const cam of S.cameras) frustum(cam, [1, 0.55, 0.1, 1]);
  frustum(start, [0.2, 0.8, 1, 1]);
  const marker = [];
  const showCameras = $("splat-cameras");
  app.on("update", () => {
    if (showCameras.checked) app.drawLineArrays(lines, lineColours, true);
    if (marker.length) app.drawLineArrays(marker, new Array((marker.length / 3) * 4).fill(1), false);
  });
  app.on("frameend", () => { state.frames += 1; });

  // ---- recolouring ----
  const modeSelect = $("splat-mode"), slider = $("splat-band"), widthInput = $("splat-width");
  const mapSelect = $("splat-colormap");
  // The slider is in nanometres, continuous over the captured range: between
  // two captured bands the view shows their linear interpolation, as `ddhgs
  // render --wavelengths` does (core::interpolation_map).
  const step = N > 1 ? Math.max(0.1, Math.round((wl[N - 1] - wl[0]) / 1000 * 10) / 10) : 1;
  slider.min = String(wl[0]);
  slider.max = String(wl[N - 1]);
  slider.step = String(step);
  slider.value = String(wl[Math.floor((N - 1) / 2)]);
  const viridis = R.viridis;
  // Vegetation indices the bands cover: one more colouring each.
  const indices = S.indices || [];
  for (const index of indices) {
    const option = document.createElement("option");
    option.value = "index:" + index.name;
    option.textContent = index.name.toUpperCase();
    modeSelect.appendChild(option);
  }
  const indexOf = (mode) => indices.find((i) => "index:" + i.name === mode);

  // The captured bands around a wavelength and the weight of the upper one.
  function bracket(nm) {
    let hi = 1;
    while (hi < N - 1 && wl[hi] < nm) ++hi;
    if (N === 1) return [0, 0, 0];
    const lo = hi - 1;
    const t = Math.min(1, Math.max(0, (nm - wl[lo]) / (wl[hi] - wl[lo])));
    // A captured wavelength (within half a slider step) is its band.
    if (Math.abs(nm - wl[lo]) <= step / 2) return [lo, lo, 0];
    if (Math.abs(nm - wl[hi]) <= step / 2) return [hi, hi, 0];
    return [lo, hi, t];
  }

  // Weights over band values -> three output channels: [N][3].
  function bandWeights() {
    const mode = modeSelect.value;
    if (mode === "rgb") return S.pseudo_rgb.weights;
    const index = indexOf(mode);
    if (index) return wl.map((_, n) => [index.a[n], index.b[n], 0]);
    const nm = Number(slider.value);
    const [a, b, t] = bracket(nm);
    const w = wl.map(() => [0, 0, 0]);
    if (mode === "band") {
      w[a] = [1 - t, 1 - t, 1 - t];
      w[b] = w[b].map((v) => v + t);
      state.bands = [a, b];
      state.nm = nm;
      return w;
    }
    const centre = t < 0.5 ? a : b;
    const half = Math.floor(Number(widthInput.value) / 2);
    const lo = Math.max(0, centre - half), hi = Math.min(N - 1, centre + half);
    for (let n = lo; n <= hi; ++n) w[n] = [1, 1, 1].map((v) => v / (hi - lo + 1));
    state.bands = [lo, hi];
    return w;
  }

  function recolour() {
    const w = bandWeights();
    const index = indexOf(modeSelect.value);
    const mode = modeSelect.value === "rgb" ? (S.pseudo_rgb.srgb_curve ? 0 : 1) : index ? 3 : 2;
    const weights = new Float32Array(3 * 4 * LAYERS);
    const offset = [0, 0, 0];
    for (let j = 0; j < 3; ++j) {
      for (let n = 0; n < N; ++n) {
        offset[j] += w[n][j] * B.mean[n];
        for (let k = 0; k < K; ++k) {
          offset[j] += w[n][j] * B.low[k] * B.vectors[k][n];
          weights[3 * k + j] += w[n][j] * (B.high[k] - B.low[k]) * B.vectors[k][n];
        }
      }
    }
    const grey = mapSelect.value === "gray" && !index;
    const table = index ? R.rdylgn : viridis;
    for (let i = 0; i < 256; ++i)
      for (let j = 0; j < 3; ++j) lut[4 * i + j] = grey ? i : table[i][j];
    for (let i = 0; i < 256; ++i) lut[4 * i + 3] = 255;
    colourMap.lock().set(lut);
    colourMap.unlock();
    material.setParameter("uWeights[0]", weights);
    material.setParameter("uOffset", new Float32Array(offset));
    material.setParameter("uMode", mode);
    // The background as the run rendered it, through the same colours.
    const bg = [0, 1, 2].map((j) => S.background.reduce((s, v, n) => s + v * w[n][j], 0));
    const srgb = (x) => { x = Math.min(1, Math.max(0, x)); return x <= 0.0031308 ? 12.92 * x : 1.055 * Math.pow(x, 1 / 2.4) - 0.055; };
    const unit = (x) => Math.min(1, Math.max(0, x));
    const bgIndex = bg[0] + bg[1] > 1e-3 ? 0.5 * ((bg[0] - bg[1]) / (bg[0] + bg[1]) + 1) : null;
    const shown = mode === 0 ? bg.map(srgb) : mode === 1 ? bg.map(unit)
      : mode === 3 ? (bgIndex === null ? [0.5, 0.5, 0.5] : R.rdylgn[Math.round(255 * unit(bgIndex))].map((v) => v / 255))
      : (grey ? [bg[0], bg[0], bg[0]] : viridis[Math.round(255 * unit(bg[0]))].map((v) => v / 255));
    camera.camera.clearColor = new pc.Color(shown[0], shown[1], shown[2]);
    state.clearColour = shown.map((v) => Math.round(255 * Math.min(1, Math.max(0, v))));
    const [lo, hi] = state.bands || [0, 0];  // set by bandWeights outside pseudo-RGB
    $("splat-label").textContent = modeSelect.value === "rgb" ? S.pseudo_rgb.title
      : index ? index.title
      : lo === hi ? "band " + lo + ": " + wl[lo].toFixed(1) + " nm"
      : modeSelect.value === "band" ? state.nm.toFixed(1) + " nm, not captured: interpolated between band " + lo +
        " (" + wl[lo].toFixed(1) + " nm) and band " + hi + " (" + wl[hi].toFixed(1) + " nm)"
      : "bands " + lo + "-" + hi + ": " + wl[lo].toFixed(1) + "-" + wl[hi].toFixed(1) + " nm (mean)";
    state.recolours += 1;
  }
  for (const control of [modeSelect, slider, widthInput, mapSelect]) control.addEventListener("input", recolour);

  // ---- picking: the Gaussians along the ray through the clicked pixel ----
  const spectrumChart = helpers.chart($("splat-spectrum"), "Spectrum of the Gaussians under the cursor",
    "wavelength nm", "reflectance", wl,
    [{ label: "alpha-blended Gaussians", values: wl.map(() => null) }, { label: "Gaussian of largest weight", values: wl.map(() => null) }],
    { width: 500, height: 300, scales: { x: { time: false }, y: { range: [0, 1] } } });
  state.spectrumChart = spectrumChart;

  function pickAt(event) {
    const rect = canvas.getBoundingClientRect();
    const ndcX = (2 * (event.clientX - rect.left)) / rect.width - 1;
    const ndcY = 1 - (2 * (event.clientY - rect.top)) / rect.height;
    const t = Math.tan((camera.camera.fov * Math.PI) / 360);
    const o = camera.getPosition();
    const d = camera.forward.clone().add(camera.right.clone().mulScalar(ndcX * t * (rect.width / rect.height)))
      .add(camera.up.clone().mulScalar(ndcY * t)).normalize();
    const hits = [];
    const q = [0, 0, 0, 0];
    for (let i = 0; i < G; ++i) {
      // Ray in the Gaussian's frame, scaled to unit standard deviations: the
      // closest approach gives the density maximum along the ray.
      for (let a = 0; a < 4; ++a) q[a] = quatSteps[4 * i + a] / 127;
      const rel = [o.x - means[3 * i], o.y - means[3 * i + 1], o.z - means[3 * i + 2]];
      const ol = rotateInverse(q, rel), dl = rotateInverse(q, [d.x, d.y, d.z]);
      let oo = 0, od = 0, dd = 0;
      for (let a = 0; a < 3; ++a) {
        const s = Math.exp(logScale(3 * i + a));
        const oa = ol[a] / s, da = dl[a] / s;
        oo += oa * oa; od += oa * da; dd += da * da;
      }
      const tMin = -od / dd;
      if (tMin <= 0) continue;
      const alpha = Math.min(0.99, (opacitySteps[i] / 255) * Math.exp(-0.5 * (oo - (od * od) / dd)));
      if (alpha >= 1 / 255) hits.push({ i, t: tMin, alpha });
    }
    hits.sort((a, b) => a.t - b.t);
    const blended = new Float64Array(N), one = new Float64Array(N);
    let transmittance = 1, strongest = null, used = 0, depthSum = 0;
    for (const h of hits) {
      const weight = h.alpha * transmittance;
      spectrumOf(h.i, one);
      for (let n = 0; n < N; ++n) blended[n] += weight * one[n];
      if (!strongest || weight > strongest.weight) strongest = { i: h.i, weight };
      depthSum += weight * h.t;
      transmittance *= 1 - h.alpha;
      used += 1;
      if (transmittance < 1e-4) break;
    }
    const coverage = 1 - transmittance;
    state.picks += 1;
    state.pick = { gaussians: used, coverage };
    if (!used) {
      $("splat-pick").textContent = "No Gaussian under the cursor.";
      return;
    }
    const strongestSpectrum = Array.from(spectrumOf(strongest.i, one));
    spectrumChart.setData([wl, Array.from(blended, (v) => v / coverage), strongestSpectrum]);
    const p = o.clone().add(d.clone().mulScalar(depthSum / coverage));
    const s = 0.01 * depth;
    marker.length = 0;
    for (let a = 0; a < 3; ++a) {
      const e = [0, 0, 0];
      e[a] = s;
      marker.push(p.x - e[0], p.y - e[1], p.z - e[2], p.x + e[0], p.y + e[1], p.z + e[2]);
    }
    $("splat-pick").textContent = used + " Gaussians along the ray, coverage " + coverage.toFixed(3) +
      " (the blend is divided by it; background left out); largest weight " +
      strongest.weight.toFixed(3) + ", Gaussian #" + strongest.i + ".";
  }

  // v rotated by the inverse of unit quaternion q = (w, x, y, z).
  function rotateInverse(q, v) {
    const [w, x, y, z] = q;
    const n = Math.hypot(w, x, y, z) || 1;
    const qw = w / n, qx = -x / n, qy = -y / n, qz = -z / n;
    const tx = 2 * (qy * v[2] - qz * v[1]), ty = 2 * (qz * v[0] - qx * v[2]), tz = 2 * (qx * v[1] - qy * v[0]);
    return [v[0] + qw * tx + (qy * tz - qz * ty), v[1] + qw * ty + (qz * tx - qx * tz), v[2] + qw * tz + (qx * ty - qy * tx)];
  }

  $("splat-note").textContent = G + " Gaussians; band values from " + K + " basis vectors with 8-bit coefficients " +
    "(RMS error " + B.rmse.toFixed(4) + " reflectance); colours are the view-independent (DC) part of each band. " +
    "Drag to orbit, right- or shift-drag to pan, wheel to zoom, click to plot a spectrum. Orange: training cameras; blue: the start view (" +
    "the first " + (R.figures.views.length ? "report view" : "view") + ").";
  recolour();
  app.start();
  state.ready = true;
  return state;
};
