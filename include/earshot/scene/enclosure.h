#pragma once
/** @file Is a point inside the volume a closed mesh bounds? For warnings on
 *  input that is valid but probably not meant (a listener outside a closed
 *  room hears nothing of it). Not on any per-ray path. */
#include "earshot/core/vec3.h"
#include "earshot/scene/ray_tracer.h"
#include "earshot/scene/triangle_mesh.h"

namespace earshot {

/** Closed (watertight): every edge, with vertices merged by position, is
 *  shared by exactly two triangles. Degenerate triangles are ignored. An
 *  empty mesh is not closed. O(triangles log triangles). */
bool isClosedMesh(const TriangleMesh& mesh);

enum class Enclosure {
  kOpenMesh,  ///< the mesh bounds no volume (not closed, or empty): no answer
  kInside,
  kOutside,
};

/** Where `p` lies relative to the volume the tracer's mesh bounds: the parity
 *  of surface crossings along three rays (majority vote, so a ray through an
 *  edge does not decide alone), each followed for at most 10000 crossings.
 *  `closed` is isClosedMesh(tracer.mesh()), computed once by the caller. */
Enclosure enclosureOf(const RayTracer& tracer, bool closed, const Vec3d& p);

}  // namespace earshot
