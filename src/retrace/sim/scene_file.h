#pragma once

// Loading a user's scene file (glTF, OBJ, PLY, FBX, ... anything Assimp reads) into a simulator Scene.
//
// Every mesh is triangulated; a triangle keeps its material's diffuse colour and, when the material has a diffuse
// texture file (looked up relative to the scene file) and the mesh has texture coordinates, that texture with the
// same mip-mapped filtering as the built-in town. Meshes without texture coordinates are shaded with their colour.
// Coordinates are converted to the simulator's town frame (Z up): files with Y up (glTF, most OBJ) are rotated
// by +90 degrees about X.

#include <filesystem>

#include "retrace/sim/scene.h"

namespace retrace {

struct SceneFileOptions {
  // Metres per file unit.
  double scale = 1.0;
  // The file's up axis: true = Y up (glTF convention), false = Z up.
  bool y_up = true;
};

// Adds the file's geometry as static meshes to `scene` (call Scene::Commit or SetTime afterwards). Throws
// InputError naming the file when Assimp cannot read it, it has no triangles, or a texture cannot be read.
void LoadSceneFile(const std::filesystem::path& path, const SceneFileOptions& options, Scene* scene);

}  // namespace retrace
