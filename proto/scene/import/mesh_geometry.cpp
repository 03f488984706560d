#include "proto/scene/import/mesh_geometry.h"

#include <limits>

namespace tcfarm::import {
namespace {

constexpr double kMinAreaRatio = 1e-12;

}  // namespace

bool HasArea(const TriangleMesh& mesh) {
  for (const auto& t : mesh.triangles) {
    Vec3 ab = Sub(mesh.vertices[t[1]], mesh.vertices[t[0]]);
    Vec3 ac = Sub(mesh.vertices[t[2]], mesh.vertices[t[0]]);
    double a = Norm(ab), b = Norm(ac);
    if (a * a >= std::numeric_limits<double>::min() && b * b >= std::numeric_limits<double>::min() &&
        Norm(CrossProduct(ab, ac)) > kMinAreaRatio * a * b) {
      return true;
    }
  }
  return false;
}

}  // namespace tcfarm::import
