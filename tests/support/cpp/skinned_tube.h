// Test support: a square tube along x as the JSON lists of a skinned mesh ("vertices",
// "triangles", "vertex_joints", "vertex_weights"), for tests of parts, pieces and
// horizons of deforming meshes.
#pragma once

#include <functional>
#include <string>
#include <utility>

namespace tcfarm::test {

struct TubeJson {
  std::string vertices, triangles, joints, weights;
};

// Rings 0 .. rings at x = x0 + step * ring, each the square [y0, y1] x [z0, z1] (corners
// 0 and 1 at y0, 0 and 3 at z0), and between rings the four sides, two triangles each.
// influence(ring): that ring's vertex joints and weights, two JSON arrays of four.
inline TubeJson SquareTube(int rings, double x0, double step, double y0, double y1, double z0, double z1,
                           const std::function<std::pair<std::string, std::string>(int ring)>& influence) {
  TubeJson tube;
  auto add = [](std::string& list, const std::string& item) { list += (list.empty() ? "" : ", ") + item; };
  for (int ring = 0; ring <= rings; ++ring) {
    const auto [joints, weights] = influence(ring);
    for (int corner = 0; corner < 4; ++corner) {
      add(tube.vertices, "[" + std::to_string(x0 + step * ring) + ", " + std::to_string(corner < 2 ? y0 : y1) + ", " +
                             std::to_string(corner == 0 || corner == 3 ? z0 : z1) + "]");
      add(tube.joints, joints);
      add(tube.weights, weights);
    }
  }
  for (int ring = 0; ring < rings; ++ring) {
    for (int corner = 0; corner < 4; ++corner) {
      const int a = 4 * ring + corner, b = 4 * ring + (corner + 1) % 4;
      add(tube.triangles, "[" + std::to_string(a) + ", " + std::to_string(b) + ", " + std::to_string(b + 4) + "], [" +
                              std::to_string(a) + ", " + std::to_string(b + 4) + ", " + std::to_string(a + 4) + "]");
    }
  }
  return tube;
}

// Every vertex on joint 0 alone.
inline std::pair<std::string, std::string> OnJointZero(int /*ring*/) { return {"[0, 0, 0, 0]", "[1, 0, 0, 0]"}; }

}  // namespace tcfarm::test
