"""hbrdf view: the page, its shaders (WebGL2, WebGPU), lighting and measured references."""
