// hbrdf view: the measurement beside the model (docs/VIEWER.md, "The measurement beside the model").
// hybridbrdf/viewer/measured.py puts the numbers in the page's data (sources_panel): per material with a
// SOURCE, the path tracer's render of the measured BRDF (a PNG data URI) and BRDF slices of the model,
// its analytic part f_a and the measurement. This script shows them for the picked material:
// viewer.js calls hbrdfPlots.show(data, index). Text from the model file or the command line (names,
// paths) reaches the document only through textContent; the plot draws its own labels on a canvas.
"use strict";
window.hbrdfPlots = (function () {
  const LUMINANCE = [0.2126, 0.7152, 0.0722];  // Rec. 709 / sRGB
  const CHANNEL_COLORS = ["#ff6a5a", "#5ad45a", "#6aa0ff"];
  const SERIES_COLORS = { model: "#f2f2f2", analytic: "#ffb347", measured: "#4fc3f7" };
  const DEG = "\u00b0", THETA = "\u03b8", PHI = "\u03c6";
  const CELL_W = 300, CELL_H = 230, LEGEND_H = 26;
  const M = { left: 54, right: 10, top: 22, bottom: 38 };  // margins of one plot inside its cell
  // readback=1 in the URL's fragment, read at each draw: the fragment can change (viewer.js redraws).
  function readback() { return new URLSearchParams(location.hash.replace(/^#/, "")).get("readback") === "1"; }
  let shown = null;  // [index, channel mode, readback, the sphere's canvas width] last drawn

  function $(id) { return document.getElementById(id); }

  // One curve for the display mode: a channel (0, 1, 2) or the luminance (-1); null where a value is missing.
  function curve(values, channel) {
    if (!values) return null;
    return values[0].map(function (_, k) {
      if (channel >= 0) return values[channel][k];
      let y = 0;
      for (let c = 0; c < 3; ++c) {
        if (values[c][k] === null) return null;
        y += LUMINANCE[c] * values[c][k];
      }
      return y;
    });
  }

  // The y range (log10, whole decades) shared by every plot of the material: from the largest value
  // down at most four decades (values at or below the floor are drawn on it).
  function decades(row, channels) {
    let hi = 0, lo = Infinity;
    row.slices.forEach(function (s) {
      ["model", "analytic", "measured"].forEach(function (key) {
        channels.forEach(function (c) {
          (curve(s[key], c) || []).forEach(function (y) {
            if (y !== null && y > 0 && isFinite(y)) { hi = Math.max(hi, y); lo = Math.min(lo, y); }
          });
        });
      });
    });
    if (!(hi > 0)) return [-2, 0];
    const top = Math.ceil(Math.log10(hi) - 1e-9);
    const bottom = Math.max(Math.floor(Math.log10(lo) + 1e-9), top - 4);
    return [Math.min(bottom, top - 1), top];
  }

  function decadeLabel(k) {
    if (k >= -3 && k <= 3) return String(Math.pow(10, k) >= 1 ? Math.round(Math.pow(10, k)) : Number(Math.pow(10, k).toPrecision(1)));
    return "1e" + k;
  }

  function drawCell(ctx, x0, y0, s, theta_o, range, channels, hasAnalytic) {
    const w = CELL_W - M.left - M.right, h = CELL_H - M.top - M.bottom;
    const px = x0 + M.left, py = y0 + M.top;
    const X = function (t) { return px + (t + 90) / 180 * w; };
    const Y = function (v) {
      const l = v > 0 ? Math.log10(v) : -Infinity;
      return py + h - (Math.min(Math.max(l, range[0]), range[1]) - range[0]) / (range[1] - range[0]) * h;
    };
    // frame, grid, ticks
    ctx.strokeStyle = "#555";
    ctx.lineWidth = 1;
    ctx.setLineDash([]);
    ctx.strokeRect(px + 0.5, py + 0.5, w, h);
    ctx.fillStyle = "#bbb";
    ctx.font = "11px sans-serif";
    ctx.textAlign = "center";
    ctx.textBaseline = "top";
    for (let t = -90; t <= 90; t += 30) {
      ctx.strokeStyle = t === 0 ? "#555" : "#333";
      ctx.beginPath(); ctx.moveTo(X(t) + 0.5, py); ctx.lineTo(X(t) + 0.5, py + h); ctx.stroke();
      ctx.textAlign = t === -90 ? "left" : t === 90 ? "right" : "center";  // clear of the y labels
      ctx.fillText(String(t), X(t), py + h + 3);
    }
    ctx.textAlign = "center";
    ctx.fillText(THETA + "o (" + DEG + "), > 0: mirror side", px + w / 2, py + h + 18);
    ctx.textAlign = "right";
    ctx.textBaseline = "middle";
    for (let k = range[0]; k <= range[1]; ++k) {
      const yy = Y(Math.pow(10, k));
      ctx.strokeStyle = "#333";
      ctx.beginPath(); ctx.moveTo(px, Math.round(yy) + 0.5); ctx.lineTo(px + w, Math.round(yy) + 0.5); ctx.stroke();
      ctx.fillText(decadeLabel(k), px - 4, yy);
    }
    ctx.save();
    ctx.translate(x0 + 11, py + h / 2);
    ctx.rotate(-Math.PI / 2);
    ctx.textAlign = "center";
    ctx.fillText("f (1/sr), log", 0, 0);
    ctx.restore();
    ctx.textAlign = "left";
    ctx.textBaseline = "alphabetic";
    ctx.fillStyle = "#ddd";
    ctx.fillText(THETA + "i = " + s.theta_i + DEG + ", " + PHI + "i = " + s.phi_i + DEG +
      (s.phi_i ? " (the alpha_y plane)" : ""), px, py - 7);
    // the curves, clipped to the plot
    ctx.save();
    ctx.beginPath();
    ctx.rect(px, py, w, h);
    ctx.clip();
    // measurement dots first, then the model (solid), then f_a (dashed) on top: where the three
    // coincide, the dashes alternate with the solid line and the dots show around them
    channels.forEach(function (c) {
      const color = function (key) { return c < 0 ? SERIES_COLORS[key] : CHANNEL_COLORS[c]; };
      ctx.fillStyle = color("measured");
      curve(s.measured, c).forEach(function (y, k) {
        if (y === null || Math.round(theta_o[k]) % 4) return;  // every fourth degree: dots, not a band
        ctx.beginPath();
        ctx.arc(X(theta_o[k]), Y(y), 2.2, 0, 2 * Math.PI);
        ctx.fill();
      });
      [["model", []], ["analytic", [6, 4]]].forEach(function (kd) {
        const ys = kd[0] === "analytic" && !hasAnalytic ? null : curve(s[kd[0]], c);
        if (!ys) return;
        ctx.strokeStyle = color(kd[0]);
        ctx.lineWidth = 1.6;
        ctx.setLineDash(kd[1]);
        ctx.beginPath();
        let open = false;
        ys.forEach(function (y, k) {
          if (y === null) { open = false; return; }
          if (open) ctx.lineTo(X(theta_o[k]), Y(y)); else ctx.moveTo(X(theta_o[k]), Y(y));
          open = true;
        });
        ctx.stroke();
      });
      ctx.setLineDash([]);
    });
    ctx.restore();
  }

  function drawLegend(ctx, width, channels, hasAnalytic) {
    let x = 8;
    const y = LEGEND_H / 2;
    ctx.font = "12px sans-serif";
    ctx.textBaseline = "middle";
    ctx.textAlign = "left";
    const color = function (key) { return channels.length === 1 ? SERIES_COLORS[key] : "#ddd"; };
    const items = [["model", "model f_t"], ["analytic", "its analytic part f_a"], ["measured", "measurement"]];
    items.forEach(function (it) {
      if (it[0] === "analytic" && !hasAnalytic) return;
      ctx.strokeStyle = color(it[0]);
      ctx.fillStyle = color(it[0]);
      ctx.lineWidth = 2;  // on whole pixels: the legend's samples are drawn in their exact colours
      if (it[0] === "measured") {
        [4, 12, 20].forEach(function (dx) { ctx.beginPath(); ctx.arc(x + dx, y, 2.2, 0, 2 * Math.PI); ctx.fill(); });
      } else {
        ctx.setLineDash(it[0] === "analytic" ? [6, 4] : []);
        ctx.beginPath(); ctx.moveTo(x, y); ctx.lineTo(x + 24, y); ctx.stroke();
        ctx.setLineDash([]);
      }
      ctx.fillStyle = "#ddd";
      ctx.fillText(it[1], x + 30, y);
      x += 40 + ctx.measureText(it[1]).width;
    });
    if (channels.length > 1) {
      ["red", "green", "blue"].forEach(function (name, c) {
        ctx.fillStyle = CHANNEL_COLORS[c];
        ctx.fillText(name, x, y);
        x += 12 + ctx.measureText(name).width;
      });
    } else {
      ctx.fillStyle = "#aaa";
      ctx.fillText("(luminance)", x, y);
    }
  }

  function drawPlots(data, row, mode) {
    const panel = data.sources_panel;
    const canvas = $("slices_plot");
    const planes = [];
    row.slices.forEach(function (s) { if (planes.indexOf(s.phi_i) < 0) planes.push(s.phi_i); });
    const cols = panel.theta_i.length;
    canvas.width = cols * CELL_W;
    canvas.height = LEGEND_H + planes.length * CELL_H;
    const ctx = canvas.getContext("2d");
    ctx.fillStyle = "#151515";
    ctx.fillRect(0, 0, canvas.width, canvas.height);
    const channels = mode === "rgb" ? [0, 1, 2] : [-1];
    const range = decades(row, channels);
    const hasAnalytic = data.has_analytic && row.slices.every(function (s) { return !!s.analytic; });
    drawLegend(ctx, canvas.width, channels, hasAnalytic);
    row.slices.forEach(function (s) {
      const col = panel.theta_i.indexOf(s.theta_i), r = planes.indexOf(s.phi_i);
      drawCell(ctx, col * CELL_W, LEGEND_H + r * CELL_H, s, panel.theta_o, range, channels, hasAnalytic);
    });
    canvas.removeAttribute("data-readback");
    if (readback()) {  // the tests read the plot back (RGBA, top row first, base64)
      const px = ctx.getImageData(0, 0, canvas.width, canvas.height).data;
      let bin = "";
      for (let i = 0; i < px.length; i += 0x8000) bin += String.fromCharCode.apply(null, px.subarray(i, i + 0x8000));
      canvas.setAttribute("data-readback", canvas.width + " " + canvas.height + " " + btoa(bin));
    }
  }

  function showImage(data, row) {
    const fig = $("measured");
    let img = fig.querySelector("img");
    if (!row.image) {  // a build without the renderer: the slices only
      fig.hidden = true;
      return;
    }
    if (!img) {  // made here, not in the page's markup: a page without sources holds no image element
      img = document.createElement("img");
      img.addEventListener("load", function () {
        img.setAttribute("data-natural", img.naturalWidth + "x" + img.naturalHeight);
      });
      fig.insertBefore(img, fig.firstChild);
    }
    const view = $("view");
    img.removeAttribute("data-natural");
    img.setAttribute("alt", "the path tracer's render of the measurement");
    img.setAttribute("width", String(view.width));
    img.setAttribute("height", String(view.height));
    img.setAttribute("src", row.image);
    const r = data.sources_panel.render;
    $("measured_caption").textContent = "The measurement " + row.source + ": the path tracer's render (" + r.width +
      " x " + r.height + ", " + r.spp + " samples per pixel, max_depth " + r.max_depth + ") in " + r.light +
      ", exposure " + r.exposure + " EV. It does not follow the controls.";
    fig.hidden = false;
  }

  function show(data, index) {
    const panel = data.sources_panel;
    const row = panel && panel.materials ? panel.materials[index] : null;
    const box = $("slices"), fig = $("measured");
    if (!row) {
      if (box) box.hidden = true;
      if (fig) fig.hidden = true;
      shown = null;
      return;
    }
    const mode = $("slices_channel").value;
    const now = [index, mode, readback(), $("view").width];
    if (shown && now.every(function (v, k) { return v === shown[k]; })) return;
    shown = now;
    showImage(data, row);
    box.hidden = false;
    drawPlots(data, row, mode);
    $("slices_caption").textContent = "BRDF slices of " + data.materials[index].name + " as fitted (the sliders' " +
      "edits are not plotted): the model f_t (solid), " + (data.has_analytic ? "its analytic part f_a (dashed) " : "") +
      "and the measurement " + row.file + " (dots), the reader's values. f without the cosine, log scale; wi at " +
      THETA + "i, wo in the plane of incidence at " + THETA + "o, " + THETA + "o = " + THETA + "i the mirror direction" +
      (row.slices.some(function (s) { return s.phi_i; }) ? "; second row: the plane " + PHI + "i = 90" + DEG +
        " (anisotropic material)" : "") + ".";
    if (!box.hasAttribute("data-wired")) {
      box.setAttribute("data-wired", "1");
      $("slices_channel").addEventListener("change", function () {
        const i = shown ? shown[0] : index;
        shown = null;
        show(data, i);
      });
    }
  }

  return { show: show };
})();
