#pragma once
/** @file glTF 2.0 (.gltf, .glb) to a TriangleMesh, with material mapping. */
#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "earshot/core/status.h"
#include "earshot/io/input_file.h"
#include "earshot/materials/material.h"
#include "earshot/scene/triangle_mesh.h"

namespace earshot {

/** The triangles one node placed: mesh.triangles[firstTriangle,
 *  firstTriangle + triangleCount), contiguous (their vertices too). */
struct GltfNodeTriangles {
  int node = -1;                      ///< index into the file's nodes
  std::string name;                   ///< the node's name, "" if it has none
  std::array<double, 16> worldMatrix{};  ///< node frame -> world, column-major 4x4 as in glTF
  uint32_t firstTriangle = 0;
  uint32_t triangleCount = 0;
};

struct GltfLoadResult {
  TriangleMesh mesh;
  std::vector<std::string> warnings;  ///< e.g. unmapped materials, skipped primitive modes
  /** One entry per visit of a node that has a mesh, in load order (the
   *  order of its triangles in `mesh`). */
  std::vector<GltfNodeTriangles> nodes;
};

/** Untrusted files (input_file.h): the file must be a regular file; external
 *  buffer and image URIs resolve inside its folder (unless
 *  limits.allowOutsidePaths) and are read within limits.maxMemoryBytes;
 *  JSON nested deeper than kMaxJsonDepth is refused before tinygltf parses
 *  it; the memory the file makes us allocate (every mesh times the paths
 *  that place it: node hierarchies are DAGs that can instance one mesh
 *  exponentially) is estimated from the accessors' counts and refused past
 *  limits.maxMemoryBytes, as are over 1e7 node placements; vertices beyond
 *  kMaxCoordinateMeters after their transform are refused (kOutOfRange).
 *  Unplaced meshes and a scene without triangles give warnings.
 *
 *  Loads every TRIANGLES primitive of the default scene (node transforms
 *  applied) and maps each glTF material to an acoustic one, in order: the
 *  `materialMap` (glTF material name -> acoustic name), the glTF material's
 *  `extras.acoustic_material`, its own name; else the default (id 0) with a
 *  warning naming it. Errors name the file and what is wrong.
 *
 *  Details: .gltf or .glb is told by the file's magic bytes, not its name;
 *  external buffers are resolved relative to the file; images are not
 *  decoded. Without a default scene, every root node (a node nobody lists as
 *  a child) is loaded. Node matrix or T*R*S transforms compose down the
 *  hierarchy; positions are taken as metres in the file's own axes (no axis
 *  conversion). Under a mirroring transform (negative determinant) each
 *  triangle's winding is reversed so its normal keeps its sense. Indices may
 *  be u8/u16/u32 or absent; positions float or normalized integers, sparse
 *  accessors applied. Other primitive modes are skipped with a warning
 *  naming mesh, primitive and mode; a primitive without a material gets id 0
 *  with a warning; a map entry naming an unknown acoustic material warns and
 *  falls through to the next rule. Each distinct warning is given once.
 *  Errors (one line, prefixed `path: `): missing file (kNotFound), malformed
 *  JSON/GLB (kParseError), accessor or buffer-view ranges outside their
 *  buffer (checked before any allocation), out-of-range indices, node
 *  cycles, non-finite vertices (kInvalidArgument, naming mesh and vertex).
 *  `materials` is only read (not owned, not kept). Thread-safe: no shared
 *  state; call from any thread. */
/** Reads a material map file: a JSON object {"glTF material name":
 *  "acoustic material name", ...}. Errors name the file and the entry. */
Result<std::map<std::string, std::string>> loadMaterialMap(const std::string& path);

Result<GltfLoadResult> loadGltf(const std::string& path, const MaterialTable& materials,
                                const std::map<std::string, std::string>& materialMap = {},
                                const InputLimits& limits = defaultInputLimits());

}  // namespace earshot
