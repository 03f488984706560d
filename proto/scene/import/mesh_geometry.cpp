#include "proto/scene/import/mesh_geometry.h"

#include <algorithm>
#include <limits>

#include "proto/scene/import/messages.h"

namespace tcfarm::import {
namespace {

constexpr double kMinAreaRatio = 1e-12;
constexpr double kPi = 3.14159265358979323846;
const Vec3 kViewFrom{0, 0.35, 1};
// Room around the bounding sphere, so the model does not touch the frame.
constexpr double kFramingMargin = 1.1;

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

void BoundingBox::Add(const Vec3& point) {
  for (int axis = 0; axis < 3; ++axis) {
    low[axis] = std::min(low[axis], point[axis]);
    high[axis] = std::max(high[axis], point[axis]);
  }
}

void BoundingBox::Add(const std::vector<Vec3>& points) {
  for (const Vec3& point : points) Add(point);
}

std::array<Vec3, 8> BoundingBox::Corners() const {
  std::array<Vec3, 8> corners;
  for (int i = 0; i < 8; ++i) {
    corners[i] = Vec3{(i & 1) ? high.x : low.x, (i & 2) ? high.y : low.y, (i & 4) ? high.z : low.z};
  }
  return corners;
}

CameraPose FramingPose(const BoundingBox& box, const std::string& displayName) {
  const Vec3 low = box.Empty() ? Vec3{} : box.low, high = box.Empty() ? Vec3{} : box.high;
  const Vec3 center{(low.x + high.x) / 2, (low.y + high.y) / 2, (low.z + high.z) / 2};
  const double radius = std::max(Norm(Sub(high, low)) / 2, 1e-3);
  const double distance = kFramingMargin * radius / std::sin(kFramingFovDegrees / 2 * kPi / 180);
  const double length = Norm(kViewFrom);
  const Vec3 position{center.x + kViewFrom.x / length * distance, center.y + kViewFrom.y / length * distance,
                      center.z + kViewFrom.z / length * distance};
  for (int axis = 0; axis < 3; ++axis) {
    if (!(std::fabs(position[axis]) <= scene_limits::kMaxMagnitude)) {
      FailInput("", displayName + ": the model spans " + std::to_string(radius * 2) + " units, too far to frame",
                "a model whose camera stays within 1e30 of the origin");
    }
  }
  return CameraPose{position, center, Vec3{0, 1, 0}};
}

}  // namespace tcfarm::import
