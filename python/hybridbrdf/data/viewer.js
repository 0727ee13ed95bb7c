// hbrdf view: the page's viewer (python/hybridbrdf/viewer.py inlines it; docs/VIEWER.md).
// Text that comes from the model file reaches the document only through textContent and
// new Option(), never as markup.
"use strict";
(function () {
  const statusEl = document.getElementById("status");
  const readbackEl = document.getElementById("readback");
  let failed = false;
  function fail(message) {
    failed = true;
    const line = String(message).split("\n")[0];
    statusEl.textContent = line;
    document.title = "hbrdf view: error: " + line;
  }
  window.addEventListener("error", function (e) { fail("script error: " + e.message); });

  const data = JSON.parse(document.getElementById("hbrdf-data").textContent);
  const params = new URLSearchParams(location.hash.replace(/^#/, ""));
  const $ = function (id) { return document.getElementById(id); };

  $("heading").textContent = "hbrdf view: " + data.model_path + " (" + data.arch + ", " +
    data.materials.length + " materials)";

  const size = Math.max(16, Math.min(2048, parseInt(params.get("size") || "320", 10) || 320));
  const canvas = $("view");
  canvas.width = size;
  canvas.height = size;
  const gl = canvas.getContext("webgl2", { antialias: false, preserveDrawingBuffer: true });
  if (!gl) {
    fail("This viewer needs WebGL2, which this browser does not provide (or has turned off).");
    return;
  }

  const NVEC = Math.ceil(data.n_pack / 4);
  const fragment = data.fragment;  // hybridbrdf.viewer.fragment_shader
  const vertex = "#version 300 es\nvoid main() { vec2 v = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));" +
    " gl_Position = vec4(v * 2.0 - 1.0, 0.0, 1.0); }\n";

  function compile(type, source) {
    const s = gl.createShader(type);
    gl.shaderSource(s, source);
    gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) {
      throw new Error("shader compile failed: " + gl.getShaderInfoLog(s));
    }
    return s;
  }
  const program = gl.createProgram();
  gl.attachShader(program, compile(gl.VERTEX_SHADER, vertex));
  gl.attachShader(program, compile(gl.FRAGMENT_SHADER, fragment));
  gl.linkProgram(program);
  if (!gl.getProgramParameter(program, gl.LINK_STATUS)) {
    throw new Error("shader link failed: " + gl.getProgramInfoLog(program));
  }
  gl.useProgram(program);
  const u = {};
  ["u_kd", "u_eta", "u_alpha", "u_pack", "u_analytic", "u_sun", "u_irradiance", "u_gain", "u_cam_pos",
    "u_cam_fwd", "u_cam_right", "u_cam_up", "u_tan", "u_size"].forEach(function (n) {
    u[n] = gl.getUniformLocation(program, n);
  });

  // Camera (the tracer's PinholeCamera).
  const cam = data.camera;
  const sub = function (a, b) { return [a[0] - b[0], a[1] - b[1], a[2] - b[2]]; };
  const cross = function (a, b) { return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]; };
  const norm = function (a) { const l = Math.hypot(a[0], a[1], a[2]); return [a[0] / l, a[1] / l, a[2] / l]; };
  const fwd = norm(sub(cam.look_at, cam.position)), right = norm(cross(fwd, cam.up)), up = cross(right, fwd);
  const tanHalf = Math.tan(0.5 * cam.fov_deg * Math.PI / 180);

  // ---- state ----
  const mats = data.materials;
  const state = { index: 0, kd: null, eta: null, alpha: null, analytic: false, exposure: 0,
                  el: data.sun.elevation, az: data.sun.azimuth };
  const select = $("material");
  mats.forEach(function (m, i) { select.add(new Option(m.name, String(i))); });

  function numbers(key, counts, lo, hi) {
    const text = params.get(key);
    if (text === null) return null;
    const v = text.split(",").map(function (x) { return x.trim() === "" ? NaN : Number(x); });
    if (counts.indexOf(v.length) < 0 || v.some(function (x) { return !isFinite(x) || x < lo || x > hi; })) {
      throw new Error("URL parameter " + key + "=" + JSON.stringify(text) + ": expected " + counts.join(" or ") +
        " numbers in [" + lo + ", " + hi + "]");
    }
    return v;
  }
  function loadMaterial(i) {
    const m = mats[i];
    state.index = i;
    state.kd = m.kd.slice();
    state.eta = m.eta.slice();
    state.alpha = m.alpha.slice();
    state.edited = { kd: false, eta: false, alpha: false };
    select.value = String(i);
  }
  function fromHash() {
    loadMaterial(0);
    if (params.has("material")) {
      const name = params.get("material");
      const i = mats.findIndex(function (m) { return m.name === name; });
      if (i < 0) throw new Error("no material " + JSON.stringify(name) + " in the model");
      loadMaterial(i);
    }
    const kd = numbers("kd", [1, 3], 0, 1);
    if (kd) { state.kd = kd.length === 1 ? [kd[0], kd[0], kd[0]] : kd; state.edited.kd = true; }
    const eta = numbers("eta", [1, 3], 1, 10);
    if (eta) { state.eta = eta.length === 1 ? [eta[0], eta[0], eta[0]] : eta; state.edited.eta = true; }
    const alpha = numbers("alpha", [1, 2], 1e-4, 1);
    if (alpha) { state.alpha = alpha.length === 1 ? [alpha[0], alpha[0]] : alpha; state.edited.alpha = true; }
    const ev = numbers("exposure", [1], -20, 20);
    if (ev) state.exposure = ev[0];
    const el = numbers("sun_el", [1], -90, 90);
    if (el) state.el = el[0];
    const az = numbers("sun_az", [1], -360, 360);
    if (az) state.az = az[0];
    state.analytic = params.get("analytic") === "1";
  }

  const sliders = { kd_r: ["kd", 0], kd_g: ["kd", 1], kd_b: ["kd", 2], eta: ["eta", -1], alpha_x: ["alpha", 0],
                    alpha_y: ["alpha", 1] };
  function show() {
    Object.keys(sliders).forEach(function (id) {
      const key = sliders[id][0], c = sliders[id][1];
      const v = c < 0 ? state[key][0] : state[key][c];
      $(id).value = String(v);
      $(id + "_v").textContent = v.toPrecision(3);
      $(id).disabled = !data.has_analytic;
    });
    $("analytic").checked = state.analytic;
    $("analytic").disabled = !data.has_analytic;
    $("exposure").value = String(state.exposure);
    $("exposure_v").textContent = state.exposure.toFixed(1);
    $("sun_el").value = String(state.el);
    $("sun_el_v").textContent = state.el.toFixed(0);
    $("sun_az").value = String(state.az);
    $("sun_az_v").textContent = state.az.toFixed(0);
    const m = mats[state.index];
    $("cmd").textContent = editCommand(m);
    $("scene").textContent = sceneJson(m);
    $("render_cmd").textContent = "hbrdf render scene.json -o out.exr --png out.png --exposure " + state.exposure +
      (edited() ? " (after the hbrdf edit above: the scene names its new material)" : "");
    $("info").textContent = "origin: " + m.origin + (data.has_analytic ? "\nfitted kd " + fitted(m.kd) + ", eta " + fitted(m.eta) +
      ", alpha " + fitted(m.alpha) : "") +
      (data.sources.length ? "\nsources given to hbrdf view: " + data.sources.join(", ") : "") +
      (data.training_sources.length ? "\ntrained on: " + data.training_sources.join(", ") : "");
  }
  function fmt(v) { return v.map(String).join(","); }  // slider values as typed: hbrdf edit rounds them to float32
  function fitted(v) { return v.map(function (x) { return x.toPrecision(4); }).join(","); }
  function quote(s) { return /^[A-Za-z0-9_.+\-\/=,:]+$/.test(s) ? s : "'" + s.replace(/'/g, "'\\''") + "'"; }
  // the edited material's name: the model contract's names have at most 64 characters
  function editName(m) { return m.name.slice(0, 59) + "_edit"; }
  function edited() { return data.has_analytic && (state.edited.kd || state.edited.eta || state.edited.alpha); }
  // hybridbrdf.viewer.tracer_scene's scene (Python fills in the rest): this material, light and size.
  function sceneJson(m) {
    const s = JSON.parse(JSON.stringify(data.scene));
    s.camera.width = size;
    s.camera.height = size;
    s.environment.sun_elevation_deg = state.el;
    s.environment.sun_azimuth_deg = state.az;
    s.materials.m.material = edited() ? editName(m) : m.name;
    s.materials.m.evaluate = state.analytic && data.has_analytic ? "analytic" : "full";
    return JSON.stringify(s, null, 1);
  }
  function editCommand(m) {
    if (!data.has_analytic) return "(the neural baseline has no analytic parameters to edit)";
    const sets = [];
    if (state.edited.kd) sets.push("kd=" + fmt(state.kd));
    if (state.edited.eta) sets.push("eta=" + fmt(state.eta));
    if (state.edited.alpha) sets.push("alpha=" + fmt(state.alpha));
    if (!sets.length) return "(move a kd, eta or alpha slider)";
    return ["hbrdf", "edit", data.model_path, m.name].map(quote).join(" ") +
      sets.map(function (s) { return " --set " + s; }).join("") + " --as " + quote(editName(m)) +
      " --out " + quote(data.model_path);
  }

  function draw() {
    const m = mats[state.index];
    gl.viewport(0, 0, size, size);
    gl.uniform3fv(u.u_kd, state.kd);
    gl.uniform3fv(u.u_eta, state.eta);
    gl.uniform2fv(u.u_alpha, state.alpha);
    const pack = new Float32Array(4 * NVEC);
    pack.set(m.pack);
    gl.uniform4fv(u.u_pack, pack);
    gl.uniform1i(u.u_analytic, state.analytic && data.has_analytic ? 1 : 0);
    const el = state.el * Math.PI / 180, az = state.az * Math.PI / 180;
    gl.uniform3fv(u.u_sun, [Math.cos(el) * Math.sin(az), Math.sin(el), -Math.cos(el) * Math.cos(az)]);
    gl.uniform1f(u.u_irradiance, data.sun_irradiance);
    gl.uniform1f(u.u_gain, Math.pow(2, state.exposure));
    gl.uniform3fv(u.u_cam_pos, cam.position);
    gl.uniform3fv(u.u_cam_fwd, fwd);
    gl.uniform3fv(u.u_cam_right, right);
    gl.uniform3fv(u.u_cam_up, up);
    gl.uniform2f(u.u_tan, tanHalf, tanHalf);
    gl.uniform2f(u.u_size, size, size);
    gl.drawArrays(gl.TRIANGLES, 0, 3);
    const err = gl.getError();
    if (err !== gl.NO_ERROR) throw new Error("WebGL error " + err);
  }
  let pending = false;
  function redraw() {
    show();
    if (pending) return;
    pending = true;
    requestAnimationFrame(function () { pending = false; try { draw(); } catch (e) { fail(e.message); } });
  }

  select.addEventListener("change", function () { loadMaterial(parseInt(select.value, 10)); redraw(); });
  Object.keys(sliders).forEach(function (id) {
    $(id).addEventListener("input", function () {
      const key = sliders[id][0], c = sliders[id][1], v = parseFloat($(id).value);
      if (c < 0) state[key] = [v, v, v]; else state[key][c] = v;
      state.edited[key] = true;
      redraw();
    });
  });
  $("analytic").addEventListener("change", function () { state.analytic = $("analytic").checked; redraw(); });
  $("exposure").addEventListener("input", function () { state.exposure = parseFloat($("exposure").value); redraw(); });
  $("sun_el").addEventListener("input", function () { state.el = parseFloat($("sun_el").value); redraw(); });
  $("sun_az").addEventListener("input", function () { state.az = parseFloat($("sun_az").value); redraw(); });
  $("reset").addEventListener("click", function () { loadMaterial(state.index); redraw(); });

  try {
    fromHash();
    show();
    draw();  // synchronously at load, so that a headless browser's --dump-dom sees the result
  } catch (e) {
    fail(e.message);
    return;
  }
  if (params.get("readback") === "1") {  // the tests read the pixels back (RGBA, bottom row first)
    const px = new Uint8Array(4 * size * size);
    gl.finish();  // drawn before reading: a readPixels that waits logs a "GPU stall" performance message
    gl.readPixels(0, 0, size, size, gl.RGBA, gl.UNSIGNED_BYTE, px);
    let bin = "";
    for (let i = 0; i < px.length; i += 0x8000) bin += String.fromCharCode.apply(null, px.subarray(i, i + 0x8000));
    readbackEl.textContent = size + " " + btoa(bin);
  }
  if (!failed) {
    statusEl.textContent = "";
    document.title = "hbrdf view: ok";
  }
})();
