// hybridbrdf renderer — scenes from JSON files (schema: docs/RENDERING.md).
#pragma once

#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include "hybridbrdf/render/limits.hpp"
#include "hybridbrdf/render/scene.hpp"

namespace hbrdf::render {

/// Makes the batched evaluator of a measured material from its "source"
/// (a path already resolved against the scene's folder, or "synthetic:NAME").
/// The Python front end supplies one built on hybridbrdf.open_source(); C++
/// callers without one cannot load scenes with measured materials.
using MeasuredFactory = std::function<BatchEval(const std::string& source)>;

struct SceneLoadOptions {
    MeasuredFactory measured;  ///< empty: "measured" materials are an error
    /// Set by another thread to stop loading (checked between materials,
    /// objects and sampler tables, and before a sky is baked): Cancelled.
    CancelFlag cancel = nullptr;
};

/// A measured material's callback failed while rendering or while its
/// tabulated sampler was built: "<scene>: <where>: <problem>", one line, e.g.
/// "scene.json: materials.gold: measured material 'gold.bsdf': ValueError: ...".
class MaterialError : public std::runtime_error {
public:
    explicit MaterialError(const std::string& what) : std::runtime_error(one_line_text(what)) {}
};

/// Reads a scene file. Relative paths inside it (meshes, environment maps,
/// model files, measured sources) are resolved against the file's folder.
/// Every problem throws FileError "<path>: <where>: <problem>", e.g.
/// "scenes/a.json: objects[1].radius: expected a number", before anything
/// large is allocated: sizes are checked against limits.hpp first.
Scene load_scene(const std::string& path, const SceneLoadOptions& options = {});

/// Same, from JSON text; `origin` names it in errors, `base_dir` resolves paths.
Scene load_scene_json(const std::string& json_text, const std::string& base_dir, const std::string& origin,
                      const SceneLoadOptions& options = {});

/// The environment light of a scene's "environment" object, given as JSON text
/// (the object itself, e.g. {"type": "sky", ...}), with the scene loader's
/// readers and errors ("<origin>: environment.<key>: <problem>"). For viewers
/// that light with the tracer's environment (hbrdf view).
EnvironmentLight load_environment_json(const std::string& json_text, const std::string& base_dir,
                                       const std::string& origin, const SceneLoadOptions& options = {});

/// A material of type "model" as a scene declares it.
struct ModelMaterialDecl {
    std::string where;          ///< "materials.paper" or "objects[2].material" (for errors)
    std::string name;           ///< the scene's name for it: its key, or the object's path when inline
    std::string file;           ///< the model file, resolved against the scene's folder
    std::string material;       ///< the material's name in that file
    bool analytic_only = false; ///< "evaluate": "analytic"
};

/// A material of another type ("analytic" or "measured"), named for messages.
struct OtherMaterialDecl {
    std::string where, name, type;
};

/// What a scene declares, read without opening any file it refers to.
struct SceneDecl {
    RenderSettings settings;
    std::vector<ModelMaterialDecl> model_materials;  ///< in file order
    std::vector<OtherMaterialDecl> other_materials;  ///< in file order
    std::vector<std::string> textured_folders;       ///< the "svbrdf" folders of textured materials, resolved
};

/// Reads a scene's settings and materials with the readers and checks of
/// load_scene_json() (same errors), without loading models, meshes or images;
/// camera, environment and the objects' geometry are not checked. The scene
/// schema as hbrdf-codegen --scene sees it.
SceneDecl read_scene_decl(const std::string& json_text, const std::string& base_dir, const std::string& origin);

}  // namespace hbrdf::render
