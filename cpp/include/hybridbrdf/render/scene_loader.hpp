// hybridbrdf renderer — scenes from JSON files (schema: docs/RENDERING.md).
#pragma once

#include <functional>
#include <string>

#include "hybridbrdf/render/scene.hpp"

namespace hbrdf::render {

/// Makes the batched evaluator of a measured material from its "source"
/// (a path already resolved against the scene's folder, or "synthetic:NAME").
/// The Python front end supplies one built on hybridbrdf.open_source(); C++
/// callers without one cannot load scenes with measured materials.
using MeasuredFactory = std::function<BatchEval(const std::string& source)>;

struct SceneLoadOptions {
    MeasuredFactory measured;  ///< empty: "measured" materials are an error
};

/// Reads a scene file. Relative paths inside it (meshes, environment maps,
/// model files, measured sources) are resolved against the file's folder.
/// Every problem throws FileError "<path>: <where>: <problem>", e.g.
/// "scenes/a.json: objects[1].radius: expected a number".
Scene load_scene(const std::string& path, const SceneLoadOptions& options = {});

/// Same, from JSON text; `origin` names it in errors, `base_dir` resolves paths.
Scene load_scene_json(const std::string& json_text, const std::string& base_dir, const std::string& origin,
                      const SceneLoadOptions& options = {});

}  // namespace hbrdf::render
