#pragma once
/** @file glTF 2.0 (.gltf, .glb) to a TriangleMesh, with material mapping. */
#include <map>
#include <string>
#include <vector>

#include "earshot/core/status.h"
#include "earshot/materials/material.h"
#include "earshot/scene/triangle_mesh.h"

namespace earshot {

struct GltfLoadResult {
  TriangleMesh mesh;
  std::vector<std::string> warnings;  ///< e.g. unmapped materials, skipped primitive modes
};

/** Loads every TRIANGLES primitive of the default scene (node transforms
 *  applied) and maps each glTF material to an acoustic one, in order: the
 *  `materialMap` (glTF material name -> acoustic name), the glTF material's
 *  `extras.acoustic_material`, its own name; else the default (id 0) with a
 *  warning naming it. Errors name the file and what is wrong. */
Result<GltfLoadResult> loadGltf(const std::string& path, const MaterialTable& materials,
                                const std::map<std::string, std::string>& materialMap = {});

}  // namespace earshot
