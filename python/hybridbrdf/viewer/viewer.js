// hbrdf view: the page's viewer (python/hybridbrdf/viewer/page.py inlines it; docs/VIEWER.md).
// Text that comes from the model file reaches the document only through textContent and
// new Option(), never as markup.
"use strict";
(function () {
  const statusEl = document.getElementById("status");
  const readbackEl = document.getElementById("readback");
  let failed = false, failedByFragment = false;
  function fail(message) {
    failed = true;
    failedByFragment = false;
    const line = String(message).split("\n")[0];
    statusEl.textContent = line;
    document.title = "hbrdf view: error: " + line;
  }
  window.addEventListener("error", function (e) { fail("script error: " + e.message); });

  const data = JSON.parse(document.getElementById("hbrdf-data").textContent);
  // The URL's fragment: read at load and again on every change of it (below, "hashchange").
  function fragment() { return new URLSearchParams(location.hash.replace(/^#/, "")); }
  let params = fragment();
  const $ = function (id) { return document.getElementById(id); };

  // A textured material (hbrdf view --svbrdf; docs/VIEWER.md "A textured material"): its layers are
  // materials of the model, fixed; the picker and the sliders are off.
  const textured = data.textured;
  $("heading").textContent = textured
    ? "hbrdf view: " + textured.folder + " (textured material, " + textured.layers.length + " layers: " +
      textured.layers.join(", ") + "; " + data.arch + ")"
    : "hbrdf view: " + data.model_path + " (" + data.arch + ", " + data.materials.length + " materials)";

  function sizeOf(p) { return Math.max(16, Math.min(2048, parseInt(p.get("size") || "320", 10) || 320)); }
  let size = sizeOf(params);
  const canvas = $("view");
  canvas.width = size;
  canvas.height = size;
  // Which backend draws (docs/VIEWER.md, "WebGPU"): WebGPU where navigator.gpu gives an adapter and
  // a device, else WebGL2; backend=webgpu|webgl2 in the URL forces one.
  const backendWanted = params.get("backend");
  if (backendWanted !== null && backendWanted !== "webgpu" && backendWanted !== "webgl2") {
    fail("URL parameter backend=" + JSON.stringify(backendWanted) + ": expected webgpu or webgl2");
    window.addEventListener("hashchange", function () { location.reload(); });  // another backend=: load again
    return;
  }

  // The environment (hybridbrdf.viewer.lighting): float32 RGB texels, rows from the zenith down.
  // Its sampling tables are built here as the tracer's EnvironmentLight builds them: weights
  // luminance x sin(theta) of the row's centre, prefix sums in double precision, a row of zeros
  // never chosen, an all-zero map sampled uniformly.
  const env = data.environment, EW = env.width, EH = env.height;
  const envTables = (function () {
    const bytes = atob(env.rgb), raw = new Uint8Array(bytes.length);
    for (let i = 0; i < bytes.length; ++i) raw[i] = bytes.charCodeAt(i);
    const rgb = new Float32Array(raw.buffer);
    const weights = new Float64Array(EW * EH), texels = new Float32Array(4 * EW * EH);
    let total = 0;
    for (let y = 0; y < EH; ++y) {
      const sinTheta = Math.sin(Math.PI * (y + 0.5) / EH);
      for (let x = 0; x < EW; ++x) {
        const i = y * EW + x, r = rgb[3 * i], g = rgb[3 * i + 1], b = rgb[3 * i + 2];
        const w = (0.2126 * r + 0.7152 * g + 0.0722 * b) * sinTheta;
        weights[i] = w > 0 && isFinite(w) ? w : 0;
        total += weights[i];
        texels[4 * i] = r; texels[4 * i + 1] = g; texels[4 * i + 2] = b;
      }
    }
    const uniform = !(total > 0);
    const marginal = new Float32Array(EH + 1), conditional = new Float32Array((EW + 1) * EH);
    let rowsSum = 0;
    for (let y = 0; y < EH; ++y) {
      let rowSum = 0;
      for (let x = 0; x < EW; ++x) rowSum += uniform ? 1 : weights[y * EW + x];
      let acc = 0;
      for (let x = 0; x < EW; ++x) {
        const w = uniform ? 1 : weights[y * EW + x];
        conditional[y * (EW + 1) + x] = rowSum > 0 ? acc / rowSum : x / EW;
        acc += w;
        // density over (u, v) of this texel: its weight over the mean weight
        texels[4 * (y * EW + x) + 3] = uniform ? 1 : w * EW * EH / total;
      }
      conditional[y * (EW + 1) + EW] = 1;
      marginal[y] = rowsSum / (uniform ? EW * EH : total);
      rowsSum += rowSum;
    }
    marginal[EH] = 1;
    return { texels: texels, marginal: marginal, conditional: conditional };
  })();

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
                  el: data.sun.elevation, az: data.sun.azimuth, light: "environment", rotation: 0 };
  // Samples per pixel to accumulate (the environment; the sun alone takes one), and per frame.
  let targetSamples = 256;
  const SAMPLES_PER_FRAME = 4;
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
  // The maps beside the sphere, as small images (their captions are text).
  if (textured) {
    const box = $("maps");
    textured.thumbnails.forEach(function (t) {
      const fig = document.createElement("figure"), img = document.createElement("img"),
        cap = document.createElement("figcaption");
      img.setAttribute("src", t.src);
      img.alt = t.label;
      cap.textContent = t.label + " (" + t.how + ")";
      fig.appendChild(img);
      fig.appendChild(cap);
      box.appendChild(fig);
    });
    box.hidden = textured.thumbnails.length === 0;
    // The picker and the sliders are one material's: not shown for a textured one (the edit line says why).
    ["material", "kd_r", "kd_g", "kd_b", "eta", "alpha_x", "alpha_y"].forEach(function (id) { $(id).parentNode.hidden = true; });
    $("reset").parentNode.hidden = true;
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
  // The state the fragment names; every parameter it leaves out at its default, so that a change of
  // the fragment shows what a fresh load of the new URL shows.
  function fromHash() {
    state.analytic = false;
    state.exposure = 0;
    state.el = data.sun.elevation;
    state.az = data.sun.azimuth;
    state.light = "environment";
    state.rotation = 0;
    targetSamples = 256;
    loadMaterial(0);
    if (params.has("material") && textured) throw new Error("URL parameter material: this page shows a textured material");
    if (params.has("material")) {
      const name = params.get("material");
      const i = mats.findIndex(function (m) { return m.name === name; });
      if (i < 0) throw new Error("no material " + JSON.stringify(name) + " in the model");
      loadMaterial(i);
    }
    if (textured && ["kd", "eta", "alpha"].some(function (k) { return params.has(k); })) {
      throw new Error("URL parameters kd, eta and alpha: a textured material's come from its maps and layers");
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
    if (params.has("light")) {
      const light = params.get("light");
      if (light !== "env" && light !== "sun") throw new Error("URL parameter light=" + JSON.stringify(light) + ": expected env or sun");
      state.light = light === "sun" ? "sun" : "environment";
    }
    const rot = numbers("rotation", [1], -360, 360);
    if (rot) state.rotation = rot[0];
    const spp = numbers("spp", [1], 1, 65536);
    if (spp) targetSamples = Math.round(spp[0]);
  }

  const sliders = { kd_r: ["kd", 0], kd_g: ["kd", 1], kd_b: ["kd", 2], eta: ["eta", -1], alpha_x: ["alpha", 0],
                    alpha_y: ["alpha", 1] };
  function show() {
    Object.keys(sliders).forEach(function (id) {
      const key = sliders[id][0], c = sliders[id][1];
      const v = c < 0 ? state[key][0] : state[key][c];
      $(id).value = String(v);
      $(id + "_v").textContent = v.toPrecision(3);
      $(id).disabled = !data.has_analytic || !!textured;
    });
    $("analytic").checked = state.analytic;
    $("analytic").disabled = !data.has_analytic;
    select.disabled = !!textured;
    $("exposure").value = String(state.exposure);
    $("exposure_v").textContent = state.exposure.toFixed(1);
    $("light").value = state.light;
    $("rotation").value = String(state.rotation);
    $("rotation_v").textContent = state.rotation.toFixed(0);
    $("rotation").disabled = state.light !== "environment";
    $("sun_el").disabled = $("sun_az").disabled = state.light !== "sun";
    $("sun_el").value = String(state.el);
    $("sun_el_v").textContent = state.el.toFixed(0);
    $("sun_az").value = String(state.az);
    $("sun_az_v").textContent = state.az.toFixed(0);
    const m = mats[state.index];
    if (window.hbrdfPlots) window.hbrdfPlots.show(data, state.index);  // viewer_plots.js: the measurement beside it
    $("cmd").textContent = editCommand(m);
    $("scene").textContent = sceneJson(m);
    $("render_cmd").textContent = "hbrdf render scene.json -o out.exr --png out.png --exposure " + state.exposure +
      (edited() ? " (after the hbrdf edit above: the scene names its new material)" : "");
    $("info").textContent = textured ? texturedInfo() : "origin: " + m.origin + (data.has_analytic ? "\nfitted kd " + fitted(m.kd) + ", eta " + fitted(m.eta) +
      ", alpha " + fitted(m.alpha) : "") +
      (data.sources.length ? "\nsources given to hbrdf view: " + data.sources.join(", ") : "") +
      (data.training_sources.length ? "\ntrained on: " + data.training_sources.join(", ") : "") +
      (data.environment.exact ? "" : "\nthe map is area-averaged from " + data.environment.source_size.join(" x ") +
       " to " + data.environment.width + " x " + data.environment.height + " texels here; the tracer's scene uses it whole");
  }
  function texturedInfo() {
    return "textured material " + textured.folder + ": " + textured.size.join(" x ") + " texels, " +
      textured.addressing + ", bilinear; layers " + textured.layers.map(function (n, k) { return k + " " + n; }).join(", ") +
      "\nuv on the sphere as the path tracer's (u = phi / 2 pi about +y, v = theta / pi from the +y pole)";
  }
  function fmt(v) { return v.map(String).join(","); }  // slider values as typed: hbrdf edit rounds them to float32
  function fitted(v) { return v.map(function (x) { return x.toPrecision(4); }).join(","); }
  function quote(s) { return /^[A-Za-z0-9_.+\-\/=,:]+$/.test(s) ? s : "'" + s.replace(/'/g, "'\\''") + "'"; }
  // the edited material's name: the model contract's names have at most 64 characters
  function editName(m) { return m.name.slice(0, 59) + "_edit"; }
  function edited() { return data.has_analytic && (state.edited.kd || state.edited.eta || state.edited.alpha); }
  // hybridbrdf.viewer.page.tracer_scene's scene (Python fills in the rest): this material, light and size.
  function sceneJson(m) {
    const s = JSON.parse(JSON.stringify(data.scene));
    s.camera.width = size;
    s.camera.height = size;
    if (state.light === "sun") {
      s.environment = JSON.parse(JSON.stringify(data.sun_environment));
      s.environment.sun_elevation_deg = state.el;
      s.environment.sun_azimuth_deg = state.az;
    } else {
      s.environment = JSON.parse(JSON.stringify(env.spec));
      s.environment.rotation_deg = state.rotation;
    }
    s.spp = state.light === "sun" ? 64 : Math.max(64, targetSamples);
    if (!textured) s.materials.m.material = edited() ? editName(m) : m.name;
    s.materials.m.evaluate = state.analytic && data.has_analytic ? "analytic" : "full";
    return JSON.stringify(s, null, 1);
  }
  function editCommand(m) {
    if (!data.has_analytic) return "(the neural baseline has no analytic parameters to edit)";
    if (textured) return "(a textured material: hbrdf paint writes its folder; the sliders are off)";
    const sets = [];
    if (state.edited.kd) sets.push("kd=" + fmt(state.kd));
    if (state.edited.eta) sets.push("eta=" + fmt(state.eta));
    if (state.edited.alpha) sets.push("alpha=" + fmt(state.alpha));
    if (!sets.length) return "(move a kd, eta or alpha slider)";
    return ["hbrdf", "edit", data.model_path, m.name].map(quote).join(" ") +
      sets.map(function (s) { return " --set " + s; }).join("") + " --as " + quote(editName(m)) +
      " --out " + quote(data.model_path);
  }

  // ---- the sums of samples per pixel, and what the backends draw with ----
  const NVEC = Math.ceil(data.n_pack / 4);
  let samples = 0;  // the backend's sums hold `samples` samples per pixel
  function samplesWanted() { return state.light === "sun" ? 1 : targetSamples; }
  // The shaders' parameters for the current state (both backends).
  function viewUniforms() {
    const pack = new Float32Array(4 * NVEC);
    pack.set(mats[state.index].pack);
    const el = state.el * Math.PI / 180, az = state.az * Math.PI / 180, rot = state.rotation * Math.PI / 180;
    return { kd: state.kd, eta: state.eta, alpha: state.alpha, pack: pack,
             analytic: state.analytic && data.has_analytic, light: state.light === "sun" ? 0 : 1,
             sun: [Math.cos(el) * Math.sin(az), Math.sin(el), -Math.cos(el) * Math.cos(az)],
             irradiance: data.sun_irradiance, rotation: [Math.cos(rot), Math.sin(rot)], envSize: [EW, EH],
             camPos: cam.position, camFwd: fwd, camRight: right, camUp: up, tan: [tanHalf, tanHalf], size: [size, size],
             layers: textured ? layerUniforms() : null };
  }
  // A textured material's layers: each its material's parameters and packed floats (4 layers; the
  // unused ones repeat the last, with weight 0).
  function layerUniforms() {
    const kd = new Float32Array(12), eta = new Float32Array(12), alpha = new Float32Array(8);
    const pack = new Float32Array(16 * NVEC);
    for (let k = 0; k < 4; ++k) {
      const m = mats[textured.layer_index[Math.min(k, textured.layers.length - 1)]];
      kd.set(m.kd, 3 * k);
      eta.set(m.eta, 3 * k);
      alpha.set(m.alpha, 2 * k);
      pack.set(m.pack, 4 * NVEC * k);
    }
    const p = textured.plane;
    return { n: textured.layers.length, kd: kd, eta: eta, alpha: alpha, pack: pack, weights: p.weights,
             planes: [p.kd, p.eta, p.alpha, p.latent], normal: p.normal };
  }

  // ---- the WebGL2 backend: sums in float textures, a draw per sample, the display pass ----
  // The interface of viewer_webgpu.js's backend (name, begin, resize, restart, accumulate, present,
  // settle, readback); here everything is synchronous: settle gives null and readback the pixels.
  function createWebGL2() {
    const gl = canvas.getContext("webgl2", { antialias: false, preserveDrawingBuffer: true });
    if (!gl) throw new Error("This viewer needs WebGL2, which this browser does not provide (or has turned off).");
    const fragment = data.fragment;  // hybridbrdf.viewer.glsl.fragment_shader
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
    function link(fragmentSource, names) {
      const program = gl.createProgram();
      gl.attachShader(program, compile(gl.VERTEX_SHADER, vertex));
      gl.attachShader(program, compile(gl.FRAGMENT_SHADER, fragmentSource));
      gl.linkProgram(program);
      if (!gl.getProgramParameter(program, gl.LINK_STATUS)) {
        throw new Error("shader link failed: " + gl.getProgramInfoLog(program));
      }
      const loc = {};
      names.forEach(function (n) { loc[n] = gl.getUniformLocation(program, n); });
      return { program: program, u: loc };
    }
    // The sums of samples live in float textures (RGBA32F render targets): core WebGL2 samples them,
    // rendering into them needs EXT_color_buffer_float, which every desktop WebGL2 exposes.
    if (!gl.getExtension("EXT_color_buffer_float")) {
      throw new Error("This viewer needs WebGL2's EXT_color_buffer_float (float render targets), which this browser does not provide.");
    }
    const accumulate = link(fragment, ["u_kd", "u_eta", "u_alpha", "u_pack", "u_analytic", "u_light", "u_sun",
      "u_irradiance", "u_env", "u_env_marginal", "u_env_conditional", "u_env_size", "u_env_rotation", "u_accum",
      "u_sample", "u_cam_pos", "u_cam_fwd", "u_cam_right", "u_cam_up", "u_tan", "u_size"]);
    const texturedNames = ["u_layer_kd", "u_layer_eta", "u_layer_alpha", "u_layer_pack", "u_layers", "u_maps",
      "u_map_size", "u_map_repeat", "u_plane_weights", "u_plane_kd", "u_plane_eta", "u_plane_alpha", "u_plane_latent", "u_plane_normal", "u_map_levels"];
    if (textured) texturedNames.forEach(function (n) { accumulate.u[n] = gl.getUniformLocation(accumulate.program, n); });
    const display = link(data.display, ["u_accum", "u_gain"]);
    const u = accumulate.u;

    function floatTexture(unit, internal, format, w, h, pixels) {
      const t = gl.createTexture();
      gl.activeTexture(gl.TEXTURE0 + unit);
      gl.bindTexture(gl.TEXTURE_2D, t);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
      gl.texImage2D(gl.TEXTURE_2D, 0, internal, w, h, 0, format, gl.FLOAT, pixels);
      return t;
    }
    floatTexture(1, gl.RGBA32F, gl.RGBA, EW, EH, envTables.texels);
    floatTexture(2, gl.R32F, gl.RED, EH + 1, 1, envTables.marginal);
    floatTexture(3, gl.R32F, gl.RED, EW + 1, EH, envTables.conditional);
    // A textured material's maps: decoded float32 RGB, one layer of a 2D array texture per map file
    // (texelFetch in the shader: its bilinear filter is the runtimes', on decoded values).
    if (textured) {
      const bytes = atob(textured.planes), raw = new Uint8Array(Math.max(bytes.length, 12));
      for (let i = 0; i < bytes.length; ++i) raw[i] = bytes.charCodeAt(i);
      const empty = textured.n_planes === 0;  // no maps: one texel, never read
      const t = gl.createTexture();
      gl.activeTexture(gl.TEXTURE5);
      gl.bindTexture(gl.TEXTURE_2D_ARRAY, t);
      gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
      gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
      gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
      const values = new Float32Array(raw.buffer), levels = empty ? 1 : textured.levels;  // a mip chain: level by level
      gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MAX_LEVEL, levels - 1);
      for (let L = 0, at = 0; L < levels; ++L) {
        const w = empty ? 1 : Math.max(1, textured.size[0] >> L), h = empty ? 1 : Math.max(1, textured.size[1] >> L);
        const n = empty ? 1 : textured.n_planes;
        gl.texImage3D(gl.TEXTURE_2D_ARRAY, L, gl.RGB32F, w, h, n, 0, gl.RGB, gl.FLOAT, values.subarray(at, at + 3 * w * h * n));
        at += 3 * w * h * n;
      }
      if (gl.getError() !== gl.NO_ERROR) throw new Error("the textured material's maps do not fit this browser's WebGL2 textures");
    }

    // Two sum textures of the canvas's size, read one and write the other (a float target cannot be
    // blended into without EXT_float_blend); made again when the size changes (the programs stay).
    function sumTargets() {
      const made = [0, 1].map(function () {
        const tex = floatTexture(4, gl.RGBA32F, gl.RGBA, size, size, null);
        const fbo = gl.createFramebuffer();
        gl.bindFramebuffer(gl.FRAMEBUFFER, fbo);
        gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, tex, 0);
        if (gl.checkFramebufferStatus(gl.FRAMEBUFFER) !== gl.FRAMEBUFFER_COMPLETE) {
          throw new Error("float framebuffer incomplete");
        }
        return { tex: tex, fbo: fbo };
      });
      gl.bindFramebuffer(gl.FRAMEBUFFER, null);
      return made;
    }
    let targets = sumTargets();

    let current = 0;  // targets[current] holds the sums
    function setUniforms(v) {
      gl.uniform3fv(u.u_kd, v.kd);
      gl.uniform3fv(u.u_eta, v.eta);
      gl.uniform2fv(u.u_alpha, v.alpha);
      gl.uniform4fv(u.u_pack, v.pack);
      gl.uniform1i(u.u_analytic, v.analytic ? 1 : 0);
      gl.uniform1i(u.u_light, v.light);
      gl.uniform3fv(u.u_sun, v.sun);
      gl.uniform1f(u.u_irradiance, v.irradiance);
      gl.uniform2f(u.u_env_rotation, v.rotation[0], v.rotation[1]);
      gl.uniform2i(u.u_env_size, v.envSize[0], v.envSize[1]);
      gl.uniform1i(u.u_env, 1);
      gl.uniform1i(u.u_env_marginal, 2);
      gl.uniform1i(u.u_env_conditional, 3);
      gl.uniform1i(u.u_accum, 0);
      gl.uniform3fv(u.u_cam_pos, v.camPos);
      gl.uniform3fv(u.u_cam_fwd, v.camFwd);
      gl.uniform3fv(u.u_cam_right, v.camRight);
      gl.uniform3fv(u.u_cam_up, v.camUp);
      gl.uniform2f(u.u_tan, v.tan[0], v.tan[1]);
      gl.uniform2f(u.u_size, v.size[0], v.size[1]);
      if (v.layers) {
        const L = v.layers;
        gl.uniform3fv(u.u_layer_kd, L.kd);
        gl.uniform3fv(u.u_layer_eta, L.eta);
        gl.uniform2fv(u.u_layer_alpha, L.alpha);
        gl.uniform4fv(u.u_layer_pack, L.pack);
        gl.uniform1i(u.u_layers, L.n);
        gl.uniform1i(u.u_maps, 5);
        gl.uniform2i(u.u_map_size, textured.size[0], textured.size[1]);
        gl.uniform1i(u.u_map_repeat, textured.addressing === "repeat" ? 1 : 0);
        gl.uniform1i(u.u_plane_weights, L.weights);
        gl.uniform4iv(u.u_plane_kd, L.planes[0]);
        gl.uniform4iv(u.u_plane_eta, L.planes[1]);
        gl.uniform4iv(u.u_plane_alpha, L.planes[2]);
        gl.uniform4iv(u.u_plane_latent, L.planes[3]);
        gl.uniform1i(u.u_plane_normal, L.normal);
        gl.uniform1i(u.u_map_levels, textured.levels);
      }
    }
    return {
      name: "WebGL2",
      begin: function () {},
      resize: function () {  // the canvas is size x size now (the fragment's size=): new sums, the same programs
        targets.forEach(function (t) { gl.deleteFramebuffer(t.fbo); gl.deleteTexture(t.tex); });
        targets = sumTargets();
        current = 0;
      },
      restart: function () {  // the picture changed: start the sums again
        targets.forEach(function (t) {
          gl.bindFramebuffer(gl.FRAMEBUFFER, t.fbo);
          gl.clearBufferfv(gl.COLOR, 0, [0, 0, 0, 0]);
        });
        gl.bindFramebuffer(gl.FRAMEBUFFER, null);
      },
      accumulate: function (first, n, v) {  // n more samples per pixel, a draw each
        gl.useProgram(accumulate.program);
        setUniforms(v);
        gl.viewport(0, 0, size, size);
        gl.activeTexture(gl.TEXTURE0);
        for (let i = 0; i < n; ++i) {
          gl.uniform1ui(u.u_sample, first + i);
          gl.bindTexture(gl.TEXTURE_2D, targets[current].tex);
          gl.bindFramebuffer(gl.FRAMEBUFFER, targets[1 - current].fbo);
          gl.drawArrays(gl.TRIANGLES, 0, 3);
          gl.bindFramebuffer(gl.FRAMEBUFFER, null);
          gl.bindTexture(gl.TEXTURE_2D, null);
          current = 1 - current;
        }
      },
      present: function (gain) {
        gl.useProgram(display.program);
        gl.activeTexture(gl.TEXTURE0);
        gl.bindTexture(gl.TEXTURE_2D, targets[current].tex);
        gl.uniform1i(display.u.u_accum, 0);
        gl.uniform1f(display.u.u_gain, gain);
        gl.viewport(0, 0, size, size);
        gl.drawArrays(gl.TRIANGLES, 0, 3);
        gl.bindTexture(gl.TEXTURE_2D, null);
        const err = gl.getError();
        if (err !== gl.NO_ERROR) throw new Error("WebGL error " + err);
      },
      settle: function () { return null; },
      readback: function () {  // the canvas's pixels (RGBA, bottom row first)
        const px = new Uint8Array(4 * size * size);
        gl.finish();  // drawn before reading: a readPixels that waits logs a "GPU stall" performance message
        gl.readPixels(0, 0, size, size, gl.RGBA, gl.UNSIGNED_BYTE, px);
        return px;
      },
    };
  }

  // ---- drawing: the same for both backends ----
  let backend = null;
  // A backend's value or Promise, then fn: synchronous for WebGL2 (the first picture is drawn at load,
  // so that a headless browser's --dump-dom sees it), chained for WebGPU.
  function then(value, fn) { return value && typeof value.then === "function" ? value.then(fn) : fn(value); }
  function showSamples() {
    $("samples").textContent = samples + " / " + samplesWanted() + " samples per pixel (" + backend.name + ")";
  }
  // SAMPLES_PER_FRAME more samples per pixel (one for the sun), after a restart when dirty.
  function accumulateFrame() {
    const n = Math.min(state.light === "sun" ? 1 : SAMPLES_PER_FRAME, samplesWanted() - samples);
    if (n <= 0) return;
    backend.accumulate(samples, n, viewUniforms());
    samples += n;
  }
  function restart() { backend.restart(); samples = 0; }
  // drawing: a picture of the fragment is being drawn (picture(), below); the frame loop waits for it.
  let pending = false, dirty = true, busy = false, again = false, drawing = false;
  function frame() {
    pending = false;
    if (failed || drawing) return;
    let settled;
    try {
      backend.begin();
      if (dirty) { restart(); dirty = false; }
      accumulateFrame();
      backend.present(Math.pow(2, state.exposure));
      showSamples();
      settled = backend.settle();
    } catch (e) {
      fail(e.message);
      return;
    }
    if (!settled) {
      if (samples < samplesWanted()) schedule();
      return;
    }
    busy = true;  // one frame of GPU work in flight at most
    settled.then(function () {
      busy = false;
      if (again || dirty || samples < samplesWanted()) { again = false; schedule(); }
    }, function (e) { fail(e.message); });
  }
  function schedule() {
    if (busy) { again = true; return; }
    if (pending || failed) return;
    pending = true;
    requestAnimationFrame(frame);
  }
  function redraw() { show(); dirty = true; schedule(); }  // the picture changed
  function reexpose() { show(); schedule(); }               // only the exposure changed

  // The controls, from the first picture on (WebGPU starts asynchronously: before it there is no
  // state or backend to change).
  function listen() {
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
    $("exposure").addEventListener("input", function () { state.exposure = parseFloat($("exposure").value); reexpose(); });
    $("light").addEventListener("change", function () { state.light = $("light").value; redraw(); });
    $("rotation").addEventListener("input", function () { state.rotation = parseFloat($("rotation").value); redraw(); });
    $("sun_el").addEventListener("input", function () { state.el = parseFloat($("sun_el").value); redraw(); });
    $("sun_az").addEventListener("input", function () { state.az = parseFloat($("sun_az").value); redraw(); });
    $("reset").addEventListener("click", function () { loadMaterial(state.index); redraw(); });
  }

  // The picture of the URL's fragment, at load and after every change of the fragment: the state
  // it names (fromHash), the canvas at its size, and with readback=1 every sample (the tests compare
  // the converged picture with the tracer's), then the pixels into #readback (RGBA, bottom row
  // first). A bad parameter is the page's one line; a later fragment can put it right.
  function picture() {
    params = fragment();
    readbackEl.textContent = "";
    try {
      fromHash();
    } catch (e) {
      fail(e.message);
      failedByFragment = true;
      return null;
    }
    if (sizeOf(params) !== size) {
      size = canvas.width = canvas.height = sizeOf(params);
      backend.begin();
      backend.resize(size);
    } else {
      backend.begin();
    }
    show();
    restart();
    dirty = false;
    const readback = params.get("readback") === "1";
    do accumulateFrame(); while (readback && samples < samplesWanted());
    const gain = Math.pow(2, state.exposure);
    backend.present(gain);
    showSamples();
    drawing = true;
    return then(backend.settle(), function () {
      if (!readback) return null;
      return then(backend.readback(gain), function (px) {
        let bin = "";
        for (let i = 0; i < px.length; i += 0x8000) bin += String.fromCharCode.apply(null, px.subarray(i, i + 0x8000));
        readbackEl.textContent = size + " " + btoa(bin);
      });
    });
  }
  // After the picture (and its readback): the frame loop goes on refining it, the title says ok.
  function pictureDone() {
    drawing = false;
    if (failed) return false;
    if (dirty || samples < samplesWanted()) schedule();  // dirty: a control moved while it was drawn
    statusEl.textContent = "";
    document.title = "hbrdf view: ok";
    return true;
  }
  function firstPicture(b) {
    backend = b;
    listen();
    return picture();
  }
  function loaded() {
    if (!pictureDone()) return;
    // Milliseconds from navigation to the first picture (bench/viewer_load.py reads it).
    document.body.dataset.loadMs = performance.now().toFixed(0);
  }
  // A new fragment (the user edits the URL, follows a link to #..., or the tests drive one tab): the
  // page shows what a fresh load of the new URL shows, without compiling its shaders again (they do
  // not depend on the fragment; docs/VIEWER.md, "URL parameters"). The title is "hbrdf view" until
  // the new picture (and its readback) is drawn, then "hbrdf view: ok" or the error. Another
  // backend=, or an error that was not the fragment's (a lost context, a refused shader, no WebGL2),
  // loads the page again; while WebGPU starts, the first picture reads the fragment it finds.
  function fragmentChanged() {
    if (!backend && !failed) return;
    if (!backend || fragment().get("backend") !== backendWanted || (failed && !failedByFragment)) {
      location.reload();
      return;
    }
    failed = failedByFragment = false;
    statusEl.textContent = "";
    document.title = "hbrdf view";
    try {
      const drawn = then(picture(), pictureDone);
      if (drawn && typeof drawn.catch === "function") drawn.catch(function (e) { fail(e.message); });
    } catch (e) {
      fail(e.message);
    }
  }
  function startWebGL2() {
    try {
      then(firstPicture(createWebGL2()), loaded);
    } catch (e) {
      fail(e.message);
    }
  }
  window.addEventListener("hashchange", fragmentChanged);
  const NO_WEBGPU = "backend=webgpu: this browser gives no WebGPU device";
  if (textured && backendWanted === "webgpu") {
    fail("backend=webgpu: the WebGPU backend does not draw textured materials (hbrdf view --svbrdf) yet; use backend=webgl2");
  } else if (backendWanted === "webgl2" || (backendWanted === null && (!navigator.gpu || textured))) {
    startWebGL2();  // synchronously at load, as before WebGPU
  } else {
    // WebGPU is asynchronous: the title stays "hbrdf view" until the first picture (and the readback)
    // is done, or says the error.
    const envCdf = new Float32Array(envTables.marginal.length + envTables.conditional.length);
    envCdf.set(envTables.marginal);
    envCdf.set(envTables.conditional, envTables.marginal.length);
    window.hbrdfWebGPU.create({ canvas: canvas, size: size, compute: data.wgsl, display: data.wgsl_display, nvec: NVEC,
                                env: { width: EW, height: EH, texels: envTables.texels, cdf: envCdf }, fail: fail })
      .then(function (got) {
        if (failed) return null;
        if (!got.backend) {
          if (backendWanted === "webgpu") { fail(NO_WEBGPU + " (" + got.why + ")."); return null; }
          startWebGL2();
          return null;
        }
        return then(firstPicture(got.backend), loaded);
      })
      .catch(function (e) { fail(e.message); });
  }
})();
