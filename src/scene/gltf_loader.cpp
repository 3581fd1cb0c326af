// glTF 2.0 loading (Khronos glTF 2.0 specification, sections "Concepts:
// Transformations", "Accessors" incl. sparse accessors and "Meshes") through
// tinygltf, into a world-space TriangleMesh with acoustic material ids.
//
// Everything read from the file is treated as hostile: accessor counts,
// offsets and strides are checked against the buffer they point into before
// any allocation or read, so a file claiming 1e12 vertices fails with a
// message instead of allocating; non-finite positions are errors.
#include "earshot/scene/gltf_loader.h"

#include <tiny_gltf.h>

#include <array>
#include <cmath>
#include <cstring>
#include <fstream>

#include <nlohmann/json.hpp>
#include <iterator>
#include <limits>
#include <set>
#include <sstream>

#include "earshot/core/math.h"
#include "earshot/io/input_file.h"

namespace earshot {
namespace {

/** 4x4 matrix, column-major like glTF: m[col * 4 + row]. */
using Mat4 = std::array<double, 16>;

constexpr Mat4 kIdentity = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
/** Vertices an accessor without a buffer view (zeros + sparse) may claim. */
constexpr size_t kMaxBufferlessCount = size_t{1} << 24;
/** Node nesting deeper than this is taken for a malformed file. */
constexpr int kMaxNodeDepth = 1024;
/** Largest file accepted (tinygltf takes 32-bit lengths). */
constexpr uint64_t kMaxFileBytes = uint64_t{2000} * 1000 * 1000;
/** Node placements (visits of the hierarchy) accepted, meshes or not. */
constexpr double kMaxNodeVisits = 1e7;
/** Bytes a loaded triangle costs downstream (material id, indices, the
 *  BVH's share: Embree's BVH4 takes ~60-100 bytes a triangle). */
constexpr double kBytesPerTriangle = 128.0;

Mat4 multiply(const Mat4& a, const Mat4& b) {
  Mat4 r{};
  for (int c = 0; c < 4; ++c)
    for (int row = 0; row < 4; ++row) {
      double s = 0;
      for (int k = 0; k < 4; ++k) s += a[k * 4 + row] * b[c * 4 + k];
      r[c * 4 + row] = s;
    }
  return r;
}

Vec3d transformPoint(const Mat4& m, const Vec3d& p) {
  return {m[0] * p.x + m[4] * p.y + m[8] * p.z + m[12], m[1] * p.x + m[5] * p.y + m[9] * p.z + m[13],
          m[2] * p.x + m[6] * p.y + m[10] * p.z + m[14]};
}

double det3(const Mat4& m) {
  return m[0] * (m[5] * m[10] - m[9] * m[6]) - m[4] * (m[1] * m[10] - m[9] * m[2]) +
         m[8] * (m[1] * m[6] - m[5] * m[2]);
}

/** tinygltf's messages as one short line: newlines joined, and cut (they
 *  may quote a whole base64 data URI). */
std::string oneLine(std::string s) {
  constexpr size_t kMaxChars = 240;
  for (char& c : s)
    if (c == '\n' || c == '\r') c = ' ';
  while (!s.empty() && s.back() == ' ') s.pop_back();
  if (s.size() > kMaxChars) s = s.substr(0, kMaxChars) + "...";
  return s;
}

std::string modeName(int mode) {
  switch (mode) {
    case TINYGLTF_MODE_POINTS: return "POINTS";
    case TINYGLTF_MODE_LINE: return "LINES";
    case TINYGLTF_MODE_LINE_LOOP: return "LINE_LOOP";
    case 3: return "LINE_STRIP";
    case TINYGLTF_MODE_TRIANGLES: return "TRIANGLES";
    case TINYGLTF_MODE_TRIANGLE_STRIP: return "TRIANGLE_STRIP";
    case TINYGLTF_MODE_TRIANGLE_FAN: return "TRIANGLE_FAN";
    default: return "unknown";
  }
}

size_t componentSize(int type) {
  switch (type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return 1;
    case TINYGLTF_COMPONENT_TYPE_SHORT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return 2;
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
    case TINYGLTF_COMPONENT_TYPE_FLOAT: return 4;
    default: return 0;
  }
}

/** One component at `p` as a double; normalized integers per glTF 2.0
 *  ("Animations"/"Accessors": max(c / (2^(n-1) - 1), -1) for signed). */
double readComponent(const unsigned char* p, int type, bool normalized) {
  switch (type) {
    case TINYGLTF_COMPONENT_TYPE_FLOAT: {
      float v;
      std::memcpy(&v, p, 4);
      return v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return normalized ? p[0] / 255.0 : p[0];
    case TINYGLTF_COMPONENT_TYPE_BYTE: {
      const double v = static_cast<signed char>(p[0]);
      return normalized ? std::max(v / 127.0, -1.0) : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
      uint16_t v;
      std::memcpy(&v, p, 2);
      return normalized ? v / 65535.0 : v;
    }
    case TINYGLTF_COMPONENT_TYPE_SHORT: {
      int16_t v;
      std::memcpy(&v, p, 2);
      return normalized ? std::max(v / 32767.0, -1.0) : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: {
      uint32_t v;
      std::memcpy(&v, p, 4);
      return v;
    }
    default: return 0.0;
  }
}

class Loader {
 public:
  Loader(const std::string& path, const tinygltf::Model& model, const MaterialTable& materials,
         const std::map<std::string, std::string>& materialMap)
      : mPath(path), mModel(model), mMaterials(materials), mMap(materialMap) {}

  Loader(const std::string& path, const tinygltf::Model& model, const MaterialTable& materials,
         const std::map<std::string, std::string>& materialMap, const InputLimits& limits)
      : Loader(path, model, materials, materialMap) {
    mLimits = limits;
  }

  Status run(GltfLoadResult* out) {
    mOut = out;
    std::vector<int> roots;
    if (mModel.defaultScene >= 0) {
      if (static_cast<size_t>(mModel.defaultScene) >= mModel.scenes.size())
        return fail("default scene " + std::to_string(mModel.defaultScene) + " does not exist");
      roots = mModel.scenes[mModel.defaultScene].nodes;
    } else {
      // No default scene: every root node (a node that is nobody's child).
      std::vector<char> isChild(mModel.nodes.size(), 0);
      for (const auto& n : mModel.nodes)
        for (int c : n.children)
          if (c >= 0 && static_cast<size_t>(c) < isChild.size()) isChild[c] = 1;
      for (size_t i = 0; i < mModel.nodes.size(); ++i)
        if (!isChild[i]) roots.push_back(static_cast<int>(i));
    }
    EARSHOT_RETURN_IF_ERROR(checkBudget(roots));
    std::vector<char> onPath(mModel.nodes.size(), 0);
    for (int r : roots) EARSHOT_RETURN_IF_ERROR(visit(r, onPath));
    for (size_t m = 0; m < mModel.meshes.size(); ++m)
      if (!mMeshUsed.count(static_cast<int>(m)))
        warnOnce(mPath + ": mesh " + (mModel.meshes[m].name.empty() ? std::to_string(m) : quotedName(mModel.meshes[m].name)) +
                 " is not placed by any node of the scene; ignored");
    if (mOut->mesh.triangles.empty())
      warnOnce(mPath + ": the scene has no triangles (an empty scene is a free field)");
    return Status::ok();
  }

 private:
  Status fail(const std::string& what) const { return parseError(mPath + ": " + what); }

  /** Adds a warning unless the same text was given already (instanced meshes). */
  void warnOnce(std::string w) {
    detail::makeOneLine(w);  // as an error's message: one line whatever the path holds
    if (mWarned.insert(w).second) mOut->warnings.push_back(w);
  }

  /** What loading will allocate, before any of it: every node visit (a node
   *  reached by k paths from the roots is placed k times: glTF's DAG of
   *  nodes can instance one mesh exponentially often) times its mesh's
   *  vertices and triangles, from the accessors' counts. Refused over the
   *  memory limit, and over kMaxNodeVisits visits whatever they hold.
   *  Iterative: no recursion on the file's depth. */
  Status checkBudget(const std::vector<int>& roots) const {
    const size_t n = mModel.nodes.size();
    std::vector<double> paths(n, 0.0);  // paths from the roots to each node (saturates at inf: fine)
    std::vector<int> indegree(n, 0);
    std::vector<char> reachable(n, 0);
    std::vector<int> stack;
    for (int r : roots) {
      if (r < 0 || static_cast<size_t>(r) >= n) return fail("node " + std::to_string(r) + " does not exist");
      paths[r] += 1.0;
      if (!reachable[r]) reachable[r] = 1, stack.push_back(r);
    }
    while (!stack.empty()) {
      const int i = stack.back();
      stack.pop_back();
      for (int c : mModel.nodes[i].children) {
        if (c < 0 || static_cast<size_t>(c) >= n) return fail("node " + std::to_string(c) + " does not exist");
        ++indegree[c];
        if (!reachable[c]) reachable[c] = 1, stack.push_back(c);
      }
    }
    // Kahn's order over the reachable nodes; what stays unordered lies on a cycle.
    for (size_t i = 0; i < n; ++i)
      if (reachable[i] && indegree[i] == 0) stack.push_back(static_cast<int>(i));
    size_t ordered = 0, reachableCount = 0;
    for (char r : reachable) reachableCount += r ? 1 : 0;
    double visits = 0, bytes = 0, triangles = 0;
    while (!stack.empty()) {
      const int i = stack.back();
      stack.pop_back();
      ++ordered;
      const tinygltf::Node& node = mModel.nodes[i];
      visits += paths[i];
      if (node.mesh >= 0 && static_cast<size_t>(node.mesh) < mModel.meshes.size()) {
        const auto [b, t] = meshCost(node.mesh);
        bytes += paths[i] * (b + sizeof(GltfNodeTriangles));
        triangles += paths[i] * t;
      }
      for (int c : node.children) {
        paths[c] += paths[i];
        if (--indegree[c] == 0) stack.push_back(c);
      }
    }
    if (ordered != reachableCount) return fail("node children form a cycle (a node is its own ancestor)");
    if (visits > kMaxNodeVisits)
      return outOfRange(mPath + ": the node hierarchy places nodes " + describeCount(visits) +
                        " times (instancing), over the limit of " + std::to_string(size_t(kMaxNodeVisits)));
    if (bytes > double(mLimits.maxMemoryBytes))
      return outOfRange(mPath + ": " + describeCount(triangles) + " triangles after instancing need about " +
                        formatBytes(bytes < 1.8e19 ? uint64_t(bytes) : UINT64_MAX) + ", over the memory limit of " +
                        formatBytes(mLimits.maxMemoryBytes) + " (--max-memory)");
    return Status::ok();
  }

  static std::string describeCount(double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, v < 1e15 ? "%.0f" : "%.3g", v);
    return buf;
  }

  /** Bytes one placement of a mesh allocates while loading (the accessors
   *  read as doubles, the stored vertices and triangles, the tracer's share
   *  per triangle) and its triangle count, from the accessors' counts. */
  std::pair<double, double> meshCost(int meshIndex) const {
    double bytes = 0, triangles = 0;
    for (const tinygltf::Primitive& prim : mModel.meshes[meshIndex].primitives) {
      if (prim.mode != TINYGLTF_MODE_TRIANGLES) continue;
      auto pos = prim.attributes.find("POSITION");
      if (pos == prim.attributes.end() || pos->second < 0 ||
          static_cast<size_t>(pos->second) >= mModel.accessors.size())
        continue;
      const double vertices = plausibleCount(pos->second);
      double indices = vertices;
      if (prim.indices >= 0) indices = plausibleCount(prim.indices);
      const double tris = std::floor(indices / 3);
      bytes += vertices * (3 * sizeof(double) + sizeof(Vec3f)) + indices * sizeof(double) + tris * kBytesPerTriangle;
      triangles += tris;
    }
    return {bytes, triangles};
  }

  /** An accessor's element count as far as its data can hold it: a count its
   *  buffer view cannot hold (or a buffer-less one over
   *  kMaxBufferlessCount) counts 0 here, and is refused by readAccessor,
   *  which names it. */
  double plausibleCount(int index) const {
    if (index < 0 || static_cast<size_t>(index) >= mModel.accessors.size()) return 0;
    const tinygltf::Accessor& acc = mModel.accessors[index];
    if (acc.bufferView < 0) return acc.count <= kMaxBufferlessCount ? double(acc.count) : 0.0;
    if (static_cast<size_t>(acc.bufferView) >= mModel.bufferViews.size()) return 0;
    const tinygltf::BufferView& view = mModel.bufferViews[acc.bufferView];
    const size_t elem = std::max<size_t>(1, componentSize(acc.componentType));
    const size_t stride = std::max(elem, view.byteStride);
    return double(acc.count) <= double(view.byteLength) / double(stride) + 1 ? double(acc.count) : 0.0;
  }

  /** Depth-first over the node hierarchy with an explicit stack. */
  Status visit(int root, std::vector<char>& onPath) {
    struct Frame {
      int node;
      Mat4 world;
      size_t nextChild;
    };
    std::vector<Frame> stack;
    auto enter = [&](int index, const Mat4& parent) -> Status {
      if (index < 0 || static_cast<size_t>(index) >= mModel.nodes.size())
        return fail("node " + std::to_string(index) + " does not exist");
      if (onPath[index]) return fail("node " + std::to_string(index) + " is its own ancestor (cycle in node children)");
      if (stack.size() > size_t(kMaxNodeDepth)) return fail("nodes nested deeper than " + std::to_string(kMaxNodeDepth));
      const tinygltf::Node& node = mModel.nodes[index];
      Mat4 local;
      EARSHOT_RETURN_IF_ERROR(localTransform(node, index, &local));
      const Mat4 world = multiply(parent, local);
      if (node.mesh >= 0) {
        GltfNodeTriangles range;
        range.node = index;
        range.name = node.name;
        range.worldMatrix = world;
        range.firstTriangle = static_cast<uint32_t>(mOut->mesh.triangles.size());
        EARSHOT_RETURN_IF_ERROR(addMesh(node.mesh, world));
        range.triangleCount = static_cast<uint32_t>(mOut->mesh.triangles.size()) - range.firstTriangle;
        mOut->nodes.push_back(std::move(range));
      }
      onPath[index] = 1;
      stack.push_back({index, world, 0});
      return Status::ok();
    };
    EARSHOT_RETURN_IF_ERROR(enter(root, kIdentity));
    while (!stack.empty()) {
      Frame& top = stack.back();
      const std::vector<int>& children = mModel.nodes[top.node].children;
      if (top.nextChild < children.size()) {
        const int child = children[top.nextChild++];
        const Mat4 world = top.world;  // `top` may move when the stack grows
        EARSHOT_RETURN_IF_ERROR(enter(child, world));
      } else {
        onPath[top.node] = 0;
        stack.pop_back();
      }
    }
    return Status::ok();
  }

  Status localTransform(const tinygltf::Node& n, int index, Mat4* out) const {
    const std::string where = "node " + std::to_string(index) + (n.name.empty() ? "" : " " + quotedName(n.name));
    if (!n.matrix.empty()) {
      if (n.matrix.size() != 16) return fail(where + ": matrix must have 16 values");
      for (int i = 0; i < 16; ++i) (*out)[i] = n.matrix[i];
    } else {
      // T * R * S (glTF 2.0 "Transformations").
      if ((!n.translation.empty() && n.translation.size() != 3) || (!n.rotation.empty() && n.rotation.size() != 4) ||
          (!n.scale.empty() && n.scale.size() != 3))
        return fail(where + ": translation/rotation/scale have the wrong number of values");
      const double tx = n.translation.empty() ? 0 : n.translation[0], ty = n.translation.empty() ? 0 : n.translation[1],
                   tz = n.translation.empty() ? 0 : n.translation[2];
      double qx = 0, qy = 0, qz = 0, qw = 1;
      if (!n.rotation.empty()) {
        qx = n.rotation[0], qy = n.rotation[1], qz = n.rotation[2], qw = n.rotation[3];
        const double len = std::sqrt(qx * qx + qy * qy + qz * qz + qw * qw);
        if (!(len > 0) || !std::isfinite(len)) return fail(where + ": rotation quaternion has no length");
        qx /= len, qy /= len, qz /= len, qw /= len;
      }
      const double sx = n.scale.empty() ? 1 : n.scale[0], sy = n.scale.empty() ? 1 : n.scale[1],
                   sz = n.scale.empty() ? 1 : n.scale[2];
      const double r[9] = {1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy + qz * qw),     2 * (qx * qz - qy * qw),
                           2 * (qx * qy - qz * qw),     1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz + qx * qw),
                           2 * (qx * qz + qy * qw),     2 * (qy * qz - qx * qw),     1 - 2 * (qx * qx + qy * qy)};
      // r is column-major: column 0 = r[0..2].
      *out = {r[0] * sx, r[1] * sx, r[2] * sx, 0, r[3] * sy, r[4] * sy, r[5] * sy, 0,
              r[6] * sz, r[7] * sz, r[8] * sz, 0, tx,        ty,        tz,        1};
    }
    for (double v : *out)
      if (!std::isfinite(v)) return fail(where + ": transform is not finite");
    return Status::ok();
  }

  /** Validates that `count` elements of `elemSize` bytes at `byteOffset` with
   *  `stride` lie inside buffer view `viewIndex`; returns the first byte. */
  Status viewRange(int viewIndex, size_t byteOffset, size_t count, size_t elemSize, size_t stride,
                   const std::string& what, const unsigned char** first) const {
    if (viewIndex < 0 || static_cast<size_t>(viewIndex) >= mModel.bufferViews.size())
      return fail(what + ": buffer view " + std::to_string(viewIndex) + " does not exist");
    const tinygltf::BufferView& view = mModel.bufferViews[viewIndex];
    if (view.buffer < 0 || static_cast<size_t>(view.buffer) >= mModel.buffers.size())
      return fail(what + ": buffer " + std::to_string(view.buffer) + " does not exist");
    const std::vector<unsigned char>& data = mModel.buffers[view.buffer].data;
    if (view.byteOffset > data.size() || view.byteLength > data.size() - view.byteOffset)
      return fail(what + ": buffer view " + std::to_string(viewIndex) + " (offset " + std::to_string(view.byteOffset) +
                  ", length " + std::to_string(view.byteLength) + ") lies outside its buffer of " +
                  std::to_string(data.size()) + " bytes");
    if (stride < elemSize) return fail(what + ": byte stride " + std::to_string(stride) + " is below the element size");
    const size_t avail = view.byteLength;
    // count elements need byteOffset + (count - 1) * stride + elemSize bytes;
    // checked by division so that absurd counts cannot overflow.
    const bool fits = count == 0 || (byteOffset <= avail && elemSize <= avail - byteOffset &&
                                     (count - 1) <= (avail - byteOffset - elemSize) / stride);
    if (!fits)
      return fail(what + ": " + std::to_string(count) + " elements do not fit in buffer view " +
                  std::to_string(viewIndex) + " (" + std::to_string(avail) + " bytes)");
    *first = data.data() + view.byteOffset + byteOffset;
    return Status::ok();
  }

  /** Reads a whole accessor as doubles, `comps` per element (sparse applied). */
  Status readAccessor(int index, int expectedType, int comps, const std::string& what, std::vector<double>* out,
                      size_t* countOut) const {
    if (index < 0 || static_cast<size_t>(index) >= mModel.accessors.size())
      return fail(what + ": accessor " + std::to_string(index) + " does not exist");
    const tinygltf::Accessor& acc = mModel.accessors[index];
    const std::string where = what + ": accessor " + std::to_string(index);
    if (acc.type != expectedType) return fail(where + " has the wrong type (expected " +
                                              std::string(expectedType == TINYGLTF_TYPE_VEC3 ? "VEC3" : "SCALAR") + ")");
    const size_t cs = componentSize(acc.componentType);
    if (cs == 0) return fail(where + " has unknown component type " + std::to_string(acc.componentType));
    const size_t elemSize = cs * comps;
    const size_t count = acc.count;
    if (acc.bufferView >= 0) {
      const size_t stride =
          (static_cast<size_t>(acc.bufferView) < mModel.bufferViews.size() &&
           mModel.bufferViews[acc.bufferView].byteStride != 0)
              ? mModel.bufferViews[acc.bufferView].byteStride
              : elemSize;
      const unsigned char* p = nullptr;
      EARSHOT_RETURN_IF_ERROR(viewRange(acc.bufferView, acc.byteOffset, count, elemSize, stride, where, &p));
      out->resize(count * comps);
      for (size_t i = 0; i < count; ++i)
        for (int c = 0; c < comps; ++c)
          (*out)[i * comps + c] = readComponent(p + i * stride + c * cs, acc.componentType, acc.normalized);
    } else {
      if (!acc.sparse.isSparse) return fail(where + " has neither a buffer view nor sparse values");
      if (count > kMaxBufferlessCount)
        return fail(where + " claims " + std::to_string(count) + " elements without a buffer view");
      out->assign(count * comps, 0.0);
    }
    if (acc.sparse.isSparse) {
      const auto& sp = acc.sparse;
      if (sp.count < 0 || static_cast<size_t>(sp.count) > count)
        return fail(where + ": sparse count " + std::to_string(sp.count) + " exceeds the accessor's count");
      const size_t n = static_cast<size_t>(sp.count);
      const size_t ics = componentSize(sp.indices.componentType);
      if (ics == 0 || sp.indices.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT ||
          sp.indices.componentType == TINYGLTF_COMPONENT_TYPE_BYTE ||
          sp.indices.componentType == TINYGLTF_COMPONENT_TYPE_SHORT)
        return fail(where + ": sparse indices must be unsigned integers");
      const unsigned char* ip = nullptr;
      const unsigned char* vp = nullptr;
      if (sp.indices.byteOffset < 0 || sp.values.byteOffset < 0) return fail(where + ": negative sparse offset");
      EARSHOT_RETURN_IF_ERROR(viewRange(sp.indices.bufferView, sp.indices.byteOffset, n, ics, ics, where + " sparse indices", &ip));
      EARSHOT_RETURN_IF_ERROR(viewRange(sp.values.bufferView, sp.values.byteOffset, n, elemSize, elemSize, where + " sparse values", &vp));
      for (size_t k = 0; k < n; ++k) {
        const double target = readComponent(ip + k * ics, sp.indices.componentType, false);
        if (target >= static_cast<double>(count))
          return fail(where + ": sparse index " + std::to_string(static_cast<uint64_t>(target)) + " is out of range");
        const size_t t = static_cast<size_t>(target);
        for (int c = 0; c < comps; ++c)
          (*out)[t * comps + c] = readComponent(vp + k * elemSize + c * cs, acc.componentType, acc.normalized);
      }
    }
    *countOut = count;
    return Status::ok();
  }

  uint32_t materialId(int gltfMaterial, const std::string& where) {
    if (gltfMaterial < 0) {
      warnOnce(where + " has no material; using the default material");
      return 0;
    }
    auto cached = mResolved.find(gltfMaterial);
    if (cached != mResolved.end()) return cached->second;
    const tinygltf::Material& gm = mModel.materials[gltfMaterial];
    const std::string label = gm.name.empty() ? "#" + std::to_string(gltfMaterial) : quotedName(gm.name);
    uint32_t id = 0;
    bool found = false;
    // 1. The caller's map (glTF material name -> acoustic name).
    auto mapped = mMap.find(gm.name);
    if (!gm.name.empty() && mapped != mMap.end()) {
      if (auto f = mMaterials.find(mapped->second)) {
        id = *f, found = true;
      } else {
        warnOnce(mPath + ": material map sends glTF material " + label +
                                 " to unknown acoustic material " + quotedName(mapped->second));
      }
    }
    // 2. extras.acoustic_material.
    if (!found && gm.extras.IsObject() && gm.extras.Has("acoustic_material")) {
      const tinygltf::Value& v = gm.extras.Get("acoustic_material");
      if (v.IsString()) {
        if (auto f = mMaterials.find(v.Get<std::string>())) {
          id = *f, found = true;
        } else {
          warnOnce(mPath + ": glTF material " + label + " names unknown acoustic material " +
                                   quotedName(v.Get<std::string>()) + " in extras.acoustic_material");
        }
      }
    }
    // 3. Its own name.
    if (!found && !gm.name.empty()) {
      if (auto f = mMaterials.find(gm.name)) id = *f, found = true;
    }
    if (!found)
      warnOnce(mPath + ": glTF material " + label +
                               " maps to no acoustic material; using the default material");
    mResolved[gltfMaterial] = id;
    return id;
  }

  Status addMesh(int meshIndex, const Mat4& world) {
    if (static_cast<size_t>(meshIndex) >= mModel.meshes.size())
      return fail("mesh " + std::to_string(meshIndex) + " does not exist");
    mMeshUsed.insert(meshIndex);
    const tinygltf::Mesh& mesh = mModel.meshes[meshIndex];
    const std::string meshLabel = "mesh " + (mesh.name.empty() ? std::to_string(meshIndex) : quotedName(mesh.name));
    const bool flip = det3(world) < 0;  // mirroring reverses winding; keep normals' sense
    TriangleMesh& out = mOut->mesh;
    for (size_t pi = 0; pi < mesh.primitives.size(); ++pi) {
      const tinygltf::Primitive& prim = mesh.primitives[pi];
      const std::string where = meshLabel + " primitive " + std::to_string(pi);
      if (prim.mode != TINYGLTF_MODE_TRIANGLES) {
        warnOnce(mPath + ": " + where + ": mode " + modeName(prim.mode) + " (" +
                                   std::to_string(prim.mode) + ") skipped, only TRIANGLES are loaded");
        continue;
      }
      auto pos = prim.attributes.find("POSITION");
      if (pos == prim.attributes.end()) return fail(where + " has no POSITION attribute");
      if (prim.material >= static_cast<int>(mModel.materials.size()))
        return fail(where + ": material " + std::to_string(prim.material) + " does not exist");
      std::vector<double> p;
      size_t vertexCount = 0;
      EARSHOT_RETURN_IF_ERROR(readAccessor(pos->second, TINYGLTF_TYPE_VEC3, 3, where + " POSITION", &p, &vertexCount));
      std::vector<double> idx;
      size_t indexCount = vertexCount;
      if (prim.indices >= 0) {
        if (static_cast<size_t>(prim.indices) >= mModel.accessors.size())
          return fail(where + ": index accessor " + std::to_string(prim.indices) + " does not exist");
        const tinygltf::Accessor& ia = mModel.accessors[prim.indices];
        if (ia.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
            ia.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
            ia.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)
          return fail(where + ": indices must be unsigned 8, 16 or 32 bit");
        EARSHOT_RETURN_IF_ERROR(readAccessor(prim.indices, TINYGLTF_TYPE_SCALAR, 1, where + " indices", &idx, &indexCount));
      }
      if (indexCount % 3 != 0)
        warnOnce(mPath + ": " + where + ": " + std::to_string(indexCount) +
                                 " indices is not a multiple of 3; the last ones are ignored");
      const size_t base = out.positions.size();
      if (base + vertexCount > std::numeric_limits<uint32_t>::max())
        return outOfRange(mPath + ": more than 2^32 vertices");
      const uint32_t material = materialId(prim.material, mPath + ": " + where);
      for (size_t v = 0; v < vertexCount; ++v) {
        const Vec3d local{p[3 * v], p[3 * v + 1], p[3 * v + 2]};
        const Vec3d w = transformPoint(world, local);
        const Vec3f stored(w);  // the engine's precision: a finite double may overflow float
        if (!isFinite(local) || !isFinite(w) || !isFinite(stored)) {
          std::ostringstream s;
          s << where << ": vertex " << v << " = (" << local.x << ", " << local.y << ", " << local.z
            << ") is not finite after the node transform (" << w.x << ", " << w.y << ", " << w.z << ")";
          return invalidArgument(mPath + ": " + s.str());
        }
        if (std::abs(w.x) > kMaxCoordinateMeters || std::abs(w.y) > kMaxCoordinateMeters ||
            std::abs(w.z) > kMaxCoordinateMeters) {
          std::ostringstream s;
          s << where << ": vertex " << v << " lies at (" << w.x << ", " << w.y << ", " << w.z
            << ") after the node transform, farther than " << kMaxCoordinateMeters << " m from the origin";
          return outOfRange(mPath + ": " + s.str());
        }
        out.positions.push_back(stored);
      }
      for (size_t t = 0; t + 2 < indexCount; t += 3) {
        std::array<uint32_t, 3> tri;
        for (int k = 0; k < 3; ++k) {
          const double i = prim.indices >= 0 ? idx[t + k] : static_cast<double>(t + k);
          if (i >= static_cast<double>(vertexCount))
            return fail(where + ": index " + std::to_string(static_cast<uint64_t>(i)) + " at position " +
                        std::to_string(t + k) + " is beyond its " + std::to_string(vertexCount) + " vertices");
          tri[k] = static_cast<uint32_t>(base + static_cast<size_t>(i));
        }
        if (flip) std::swap(tri[1], tri[2]);
        out.triangles.push_back(tri);
        out.materialIds.push_back(material);
      }
    }
    return Status::ok();
  }

  const std::string& mPath;
  const tinygltf::Model& mModel;
  const MaterialTable& mMaterials;
  const std::map<std::string, std::string>& mMap;
  GltfLoadResult* mOut = nullptr;
  InputLimits mLimits;
  std::set<int> mMeshUsed;
  std::map<int, uint32_t> mResolved;       // glTF material -> acoustic id
  std::set<std::string> mWarned;
};

/** Image decoding is not needed for acoustics: accept and drop images. */
bool skipImage(tinygltf::Image*, const int, std::string*, std::string*, int, int, const unsigned char*, int, void*) {
  return true;
}

/** tinygltf's file access for external buffers and images (URIs), confined
 *  to the glTF file's folder and to regular files within the memory limit. */
struct ConfinedFs {
  std::string folder;       // the glTF file's folder
  std::string gltfPath;
  InputLimits limits;
  uint64_t bytesRead = 0;
  std::string refused;      // the first refusal, reported instead of tinygltf's "not found"

  /** The path tinygltf built (folder + "/" + uri, or "./" + uri), if allowed. */
  bool allowed(const std::string& joined) {
    std::string uri = joined;
    if (uri.rfind(folder + "/", 0) == 0) uri = uri.substr(folder.size() + 1);
    else if (uri.rfind("./", 0) == 0) uri = uri.substr(2);
    auto r = resolveReference(folder, gltfPath + ": buffer or image uri", uri, limits.allowOutsidePaths);
    if (!r) {
      if (refused.empty()) refused = r.status().message();
      return false;
    }
    return true;
  }

  static bool exists(const std::string& path, void* self) {
    auto* fs = static_cast<ConfinedFs*>(self);
    if (!fs->allowed(path)) return false;
    std::ifstream probe(path, std::ios::binary);
    return probe.good();
  }
  static std::string expand(const std::string& path, void*) { return path; }
  static bool read(std::vector<unsigned char>* out, std::string* err, const std::string& path, void* self) {
    auto* fs = static_cast<ConfinedFs*>(self);
    if (!fs->allowed(path)) {
      if (err) *err = "refused";
      return false;
    }
    const uint64_t left = fs->limits.maxMemoryBytes > fs->bytesRead ? fs->limits.maxMemoryBytes - fs->bytesRead : 0;
    auto bytes = readInputFile(path, "glTF buffer or image", std::min<uint64_t>(left, kMaxFileBytes));
    if (!bytes) {
      if (fs->refused.empty()) fs->refused = fs->gltfPath + ": " + bytes.status().message();
      if (err) *err = "refused";
      return false;
    }
    fs->bytesRead += bytes->size();
    out->assign(bytes->begin(), bytes->end());
    return true;
  }
  static bool write(std::string* err, const std::string&, const std::vector<unsigned char>&, void*) {
    if (err) *err = "earshot never writes through tinygltf";
    return false;
  }
};

/** The JSON part of a .gltf (the whole file) or .glb (its first chunk). */
std::string_view jsonPart(const std::string& bytes, bool binary) {
  if (!binary) return bytes;
  if (bytes.size() < 20) return {};
  uint32_t chunkLength = 0;
  std::memcpy(&chunkLength, bytes.data() + 12, 4);
  return std::string_view(bytes).substr(20, chunkLength);
}

}  // namespace

Result<GltfLoadResult> loadGltf(const std::string& path, const MaterialTable& materials,
                                const std::map<std::string, std::string>& materialMap, const InputLimits& limits) {
  auto read = readInputFile(path, "glTF file", std::min<uint64_t>(kMaxFileBytes, limits.maxMemoryBytes));
  if (!read) return read.status();
  const std::string& bytes = *read;

  const std::string baseDir = folderOf(path).empty() ? std::string(".") : folderOf(path);
  const bool binary = bytes.size() >= 4 && std::memcmp(bytes.data(), "glTF", 4) == 0;
  // tinygltf parses JSON recursively (its Value tree): cap the nesting first.
  EARSHOT_RETURN_IF_ERROR(checkJsonDepth(jsonPart(bytes, binary), path));

  ConfinedFs confined{baseDir, path, limits, bytes.size(), {}};
  tinygltf::TinyGLTF parser;
  parser.SetImageLoader(&skipImage, nullptr);
  tinygltf::FsCallbacks callbacks{};
  callbacks.FileExists = &ConfinedFs::exists;
  callbacks.ExpandFilePath = &ConfinedFs::expand;
  callbacks.ReadWholeFile = &ConfinedFs::read;
  callbacks.WriteWholeFile = &ConfinedFs::write;
  callbacks.user_data = &confined;
  parser.SetFsCallbacks(callbacks);
  tinygltf::Model model;
  std::string err, warn;
  bool ok = false;
  try {
    ok = binary ? parser.LoadBinaryFromMemory(&model, &err, &warn, reinterpret_cast<const unsigned char*>(bytes.data()),
                                              static_cast<unsigned>(bytes.size()), baseDir)
                : parser.LoadASCIIFromString(&model, &err, &warn, reinterpret_cast<const char*>(bytes.data()),
                                             static_cast<unsigned>(bytes.size()), baseDir);
  } catch (const std::exception& e) {
    ok = false;
    err = e.what();
  }
  if (!confined.refused.empty() && !ok) return invalidArgument(confined.refused);
  if (!ok) return parseError(path + ": invalid glTF: " + oneLine(jsonErrorWithoutContent(err.empty() ? "unknown error" : err)));

  GltfLoadResult result;
  if (!confined.refused.empty()) result.warnings.push_back(confined.refused);
  if (!warn.empty()) result.warnings.push_back(displayPath(path) + ": " + oneLine(jsonErrorWithoutContent(warn)));
  Loader loader(path, model, materials, materialMap, limits);
  EARSHOT_RETURN_IF_ERROR(loader.run(&result));
  return result;
}

Result<std::map<std::string, std::string>> loadMaterialMap(const std::string& path) {
  auto text = readInputFile(path, "material map", kMaxJsonFileBytes);
  if (!text) return text.status();
  EARSHOT_RETURN_IF_ERROR(checkJsonDepth(*text, path));
  nlohmann::json j = nlohmann::json::parse(*text, nullptr, false);
  if (j.is_discarded()) return parseError(path + ": not valid JSON");
  if (!j.is_object()) return parseError(path + ": material map must be an object {\"gltf name\": \"acoustic name\"}");
  std::map<std::string, std::string> map;
  for (auto& [k, v] : j.items()) {
    if (!v.is_string()) return parseError(path + ": " + quotedName(k) + " must map to a material name (string)");
    map[k] = v.get<std::string>();
  }
  return map;
}

}  // namespace earshot
