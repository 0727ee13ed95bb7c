// hbrdf view: the WebGPU backend (python/hybridbrdf/viewer/page.py inlines it before viewer.js, in the
// page's one script; docs/VIEWER.md, "WebGPU"). viewer.js keeps the page's state and controls and
// draws through a backend of this small interface, which its WebGL2 backend has too:
//   name                     "WebGPU"
//   begin()                  before a frame's calls (here: error scopes)
//   resize(n)                the canvas is n x n pixels now (the fragment's size=): new sums, the
//                            same compiled pipelines
//   restart()                the sums of samples back to zero
//   accumulate(first, n, u)  n more samples per pixel (sample indices first .. first + n - 1), one
//                            compute dispatch each; u: viewer.js's viewUniforms()
//   present(gain)            the display pass to the canvas
//   settle()                 a Promise: the frame's GPU work done, its errors (if any) as a rejection
//   readback(gain)           a Promise of the display pass's pixels, RGBA8, bottom row first (as
//                            WebGL2's readPixels)
// The WGSL comes from Python (hybridbrdf.viewer.wgsl): the generated code of the model and the
// page's compute shader, and the display pass.
window.hbrdfWebGPU = (function () {
  "use strict";
  const PARAMS_HEAD_FLOATS = 40;  // hybridbrdf.viewer.wgsl.PARAMS_HEAD_BYTES / 4
  const WORKGROUP = 8;            // hybridbrdf.viewer.wgsl.WORKGROUP
  const SLOT = 256;               // bytes between sample indices (minUniformBufferOffsetAlignment's default)
  const SLOTS = 64;               // sample indices written at once (one submit per 64 dispatches at most)

  // The adapter's device, or null when the browser gives none (no navigator.gpu, no adapter, or
  // requestDevice refused): then the page draws with WebGL2, or says so for backend=webgpu.
  async function requestDevice() {
    if (!navigator.gpu) return { device: null, why: "navigator.gpu is absent" };
    const adapter = await navigator.gpu.requestAdapter();
    if (!adapter) return { device: null, why: "navigator.gpu.requestAdapter() gave no adapter" };
    try {
      return { device: await adapter.requestDevice(), why: "" };
    } catch (e) {
      return { device: null, why: "requestDevice() failed: " + e.message };
    }
  }

  async function checkModule(module, what) {
    const info = await module.getCompilationInfo();
    const errors = info.messages.filter(function (m) { return m.type === "error"; });
    if (errors.length) {
      const m = errors[0];
      throw new Error(what + " WGSL compile failed: line " + m.lineNum + ":" + m.linePos + ": " + m.message);
    }
  }

  // Rejects with the first error the scopes caught (validation, out of memory, internal).
  function popScopes(device) {
    return Promise.all([device.popErrorScope(), device.popErrorScope(), device.popErrorScope()]).then(function (errs) {
      const e = errs.find(function (x) { return x; });
      if (e) throw new Error("WebGPU error: " + e.message);
    });
  }
  function pushScopes(device) {
    device.pushErrorScope("validation");
    device.pushErrorScope("out-of-memory");
    device.pushErrorScope("internal");
  }

  // opts: canvas, size, compute (WGSL), display (WGSL), nvec (vec4s of the packed material),
  // env: { width, height, texels (Float32Array, 4 per texel), cdf (Float32Array: the rows' CDF,
  // then each row's) }, fail (the page's one-line error). Resolves to the backend, or to
  // { backend: null, why } when the browser gives no WebGPU device.
  async function create(opts) {
    const got = await requestDevice();
    if (!got.device) return { backend: null, why: got.why };
    const device = got.device;
    let size = opts.size;
    let lost = false;
    device.lost.then(function (info) {
      lost = true;
      opts.fail("WebGPU device lost: " + (info.message || info.reason));
    });
    device.addEventListener("uncapturederror", function (e) { opts.fail("WebGPU error: " + e.error.message); });

    const context = opts.canvas.getContext("webgpu");
    if (!context) throw new Error("WebGPU: the canvas gives no webgpu context");
    const format = navigator.gpu.getPreferredCanvasFormat();
    context.configure({ device: device, format: format, alphaMode: "opaque" });

    pushScopes(device);
    const computeModule = device.createShaderModule({ code: opts.compute, label: "hbrdf view compute" });
    const displayModule = device.createShaderModule({ code: opts.display, label: "hbrdf view display" });
    await checkModule(computeModule, "compute");
    await checkModule(displayModule, "display");
    const C = GPUShaderStage.COMPUTE, F = GPUShaderStage.FRAGMENT;
    const computeLayout = device.createBindGroupLayout({ entries: [
      { binding: 0, visibility: C, buffer: { type: "uniform" } },
      { binding: 1, visibility: C, buffer: { type: "uniform", hasDynamicOffset: true } },
      { binding: 2, visibility: C, buffer: { type: "storage" } },
      { binding: 3, visibility: C, buffer: { type: "read-only-storage" } },
      { binding: 4, visibility: C, buffer: { type: "read-only-storage" } }] });
    const displayLayout = device.createBindGroupLayout({ entries: [
      { binding: 0, visibility: F, buffer: { type: "read-only-storage" } },
      { binding: 1, visibility: F, buffer: { type: "uniform" } }] });
    const computePipeline = await device.createComputePipelineAsync({
      layout: device.createPipelineLayout({ bindGroupLayouts: [computeLayout] }),
      compute: { module: computeModule, entryPoint: "hbrdf_view_main" } });
    // The display pass to the canvas's format and, for the readback, to rgba8unorm (exact bytes in
    // RGBA order whatever the canvas's format: bgra8unorm needs no swizzle in the shader, only here).
    const displayPipelines = {};
    for (const f of format === "rgba8unorm" ? [format] : [format, "rgba8unorm"]) {
      displayPipelines[f] = await device.createRenderPipelineAsync({
        layout: device.createPipelineLayout({ bindGroupLayouts: [displayLayout] }),
        vertex: { module: displayModule, entryPoint: "hbrdf_view_vertex" },
        fragment: { module: displayModule, entryPoint: "hbrdf_view_fragment", targets: [{ format: f }] },
        primitive: { topology: "triangle-list" } });
    }

    const U = GPUBufferUsage;
    function buffer(bytes, usage, data) {
      const b = device.createBuffer({ size: Math.max(16, Math.ceil(bytes / 4) * 4), usage: usage });
      if (data) device.queue.writeBuffer(b, 0, data);
      return b;
    }
    const paramsData = new ArrayBuffer(4 * (PARAMS_HEAD_FLOATS + 4 * opts.nvec));
    const paramsF = new Float32Array(paramsData), paramsU = new Uint32Array(paramsData);
    const paramsBuffer = buffer(paramsData.byteLength, U.UNIFORM | U.COPY_DST);
    const frameData = new Uint32Array(SLOT / 4 * SLOTS);
    const frameBuffer = buffer(frameData.byteLength, U.UNIFORM | U.COPY_DST);
    let accum = buffer(16 * size * size, U.STORAGE | U.COPY_DST);
    const texels = buffer(opts.env.texels.byteLength, U.STORAGE | U.COPY_DST, opts.env.texels);
    const cdf = buffer(opts.env.cdf.byteLength, U.STORAGE | U.COPY_DST, opts.env.cdf);
    const displayData = new ArrayBuffer(16);
    const displayBuffer = buffer(16, U.UNIFORM | U.COPY_DST);
    // The bind groups of the sums' buffer (made again with it when the size changes).
    function groups() {
      return {
        compute: device.createBindGroup({ layout: computeLayout, entries: [
          { binding: 0, resource: { buffer: paramsBuffer } },
          { binding: 1, resource: { buffer: frameBuffer, size: 16 } },
          { binding: 2, resource: { buffer: accum } },
          { binding: 3, resource: { buffer: texels } },
          { binding: 4, resource: { buffer: cdf } }] }),
        display: device.createBindGroup({ layout: displayLayout, entries: [
          { binding: 0, resource: { buffer: accum } },
          { binding: 1, resource: { buffer: displayBuffer } }] }) };
    }
    let bound = groups();
    await popScopes(device);

    function writeParams(u) {
      paramsF.fill(0);
      paramsF.set(u.kd, 0);
      paramsF.set(u.eta, 4);
      paramsF.set(u.alpha, 8);
      paramsF.set(u.tan, 10);
      paramsF.set(u.sun, 12);
      paramsF[15] = u.irradiance;
      paramsF.set(u.camPos, 16);
      paramsF.set(u.camFwd, 20);
      paramsF.set(u.camRight, 24);
      paramsF.set(u.camUp, 28);
      paramsF.set(u.rotation, 32);
      paramsF.set(u.size, 34);
      paramsU[36] = u.analytic ? 1 : 0;
      paramsU[37] = u.light;
      paramsU[38] = u.envSize[0];
      paramsU[39] = u.envSize[1];
      paramsF.set(u.pack, PARAMS_HEAD_FLOATS);
      device.queue.writeBuffer(paramsBuffer, 0, paramsData);
    }
    function displayPass(encoder, view, f, gain) {
      new Float32Array(displayData, 0, 1)[0] = gain;
      new Uint32Array(displayData, 4, 1)[0] = size;
      device.queue.writeBuffer(displayBuffer, 0, displayData);
      const pass = encoder.beginRenderPass({ colorAttachments: [{ view: view, clearValue: [0, 0, 0, 1], loadOp: "clear",
                                                                   storeOp: "store" }] });
      pass.setPipeline(displayPipelines[f]);
      pass.setBindGroup(0, bound.display);
      pass.draw(3);
      pass.end();
    }
    let readTexture = null, readBuffer = null;
    let bytesPerRow = Math.ceil(4 * size / 256) * 256;

    return { backend: {
      name: "WebGPU",
      begin: function () { pushScopes(device); },
      resize: function (n) {  // within a frame's error scopes (begin)
        accum.destroy();
        if (readTexture) { readTexture.destroy(); readBuffer.destroy(); readTexture = readBuffer = null; }
        size = n;
        bytesPerRow = Math.ceil(4 * size / 256) * 256;
        accum = buffer(16 * size * size, U.STORAGE | U.COPY_DST);
        bound = groups();
      },
      restart: function () {
        const encoder = device.createCommandEncoder();
        encoder.clearBuffer(accum);
        device.queue.submit([encoder.finish()]);
      },
      accumulate: function (first, n, u) {
        writeParams(u);
        const groups = Math.ceil(size / WORKGROUP);
        for (let done = 0; done < n; done += SLOTS) {
          const k = Math.min(SLOTS, n - done);
          for (let i = 0; i < k; ++i) frameData[i * SLOT / 4] = first + done + i;
          device.queue.writeBuffer(frameBuffer, 0, frameData, 0, k * SLOT / 4);
          const encoder = device.createCommandEncoder();
          for (let i = 0; i < k; ++i) {  // a pass each: the next sample reads the sums this one wrote
            const pass = encoder.beginComputePass();
            pass.setPipeline(computePipeline);
            pass.setBindGroup(0, bound.compute, [i * SLOT]);
            pass.dispatchWorkgroups(groups, groups, 1);
            pass.end();
          }
          device.queue.submit([encoder.finish()]);
        }
      },
      present: function (gain) {
        const encoder = device.createCommandEncoder();
        displayPass(encoder, context.getCurrentTexture().createView(), format, gain);
        device.queue.submit([encoder.finish()]);
      },
      settle: function () {
        return Promise.all([popScopes(device), device.queue.onSubmittedWorkDone()]).then(function () {
          if (lost) throw new Error("WebGPU device lost");
        });
      },
      readback: function (gain) {
        if (!readTexture) {
          readTexture = device.createTexture({ size: [size, size], format: "rgba8unorm",
                                               usage: GPUTextureUsage.RENDER_ATTACHMENT | GPUTextureUsage.COPY_SRC });
          readBuffer = device.createBuffer({ size: bytesPerRow * size, usage: U.MAP_READ | U.COPY_DST });
        }
        pushScopes(device);
        const encoder = device.createCommandEncoder();
        displayPass(encoder, readTexture.createView(), "rgba8unorm", gain);
        encoder.copyTextureToBuffer({ texture: readTexture }, { buffer: readBuffer, bytesPerRow: bytesPerRow },
                                    [size, size]);
        device.queue.submit([encoder.finish()]);
        return popScopes(device).then(function () { return readBuffer.mapAsync(GPUMapMode.READ); }).then(function () {
          const rows = new Uint8Array(readBuffer.getMappedRange());
          const px = new Uint8Array(4 * size * size);
          for (let y = 0; y < size; ++y) {  // texture rows from the top; the readback's from the bottom
            px.set(rows.subarray(y * bytesPerRow, y * bytesPerRow + 4 * size), (size - 1 - y) * 4 * size);
          }
          readBuffer.unmap();
          return px;
        });
      },
    }, why: "" };
  }

  return { create: create };
})();
