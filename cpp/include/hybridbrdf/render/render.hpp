// hybridbrdf renderer — umbrella header of the reference path tracer
// (docs/RENDERING.md): scene loading, rendering, image output.
#pragma once

#include "hybridbrdf/render/camera.hpp"
#include "hybridbrdf/render/distribution.hpp"
#include "hybridbrdf/render/environment.hpp"
#include "hybridbrdf/render/frame.hpp"
#include "hybridbrdf/render/image.hpp"
#include "hybridbrdf/render/integrator.hpp"
#include "hybridbrdf/render/limits.hpp"
#include "hybridbrdf/render/material.hpp"
#include "hybridbrdf/render/mesh.hpp"
#include "hybridbrdf/render/progress.hpp"
#include "hybridbrdf/render/ray_cone.hpp"
#include "hybridbrdf/render/rng.hpp"
#include "hybridbrdf/render/scene.hpp"
#include "hybridbrdf/render/scene_loader.hpp"
#include "hybridbrdf/render/settings.hpp"
#include "hybridbrdf/render/sky.hpp"
#include "hybridbrdf/render/svbrdf_io.hpp"
