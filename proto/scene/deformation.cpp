#include "proto/scene/deformation.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <string>
#include <utility>

#include "proto/scene/scene.h"

namespace tcfarm {
namespace {

// a + (b - a) * t, as AnimatedVec3 joins keys: a weight that does not change between two
// keys stays exactly the key's.
double Lerp(double a, double b, double t) { return a + (b - a) * t; }

Vec3 Add(const Vec3& a, const Vec3& b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
Vec3 Scaled(const Vec3& v, double s) { return {v.x * s, v.y * s, v.z * s}; }


void Morph(const MorphTargets& morph, const std::vector<double>& weights, DeformedVertices& out) {
  for (size_t target = 0; target < morph.TargetCount(); ++target) {
    const double weight = weights[target];
    if (weight == 0) continue;  // adds nothing, and a zero weight leaves the bits as they are
    const auto& positions = morph.positionDeltas[target];
    for (size_t v = 0; v < out.positions.size(); ++v) out.positions[v] = Add(out.positions[v], Scaled(positions[v], weight));
    const auto& normals = morph.normalDeltas[target];
    if (normals.empty() || out.normals.empty()) continue;
    for (size_t v = 0; v < out.normals.size(); ++v) out.normals[v] = Add(out.normals[v], Scaled(normals[v], weight));
  }
}

void SkinVertices(const Skin& skin, const std::vector<Affine>& matrices, DeformedVertices& out) {
  const size_t k = static_cast<size_t>(skin.influencesPerVertex);
  for (size_t v = 0; v < out.positions.size(); ++v) {
    // The vertex's blended skin matrix, then one product: the same sum of the same terms in
    // the same order wherever the vertex is skinned.
    Affine blended;
    for (auto& row : blended.linear) {
      for (double& value : row) value = 0;
    }
    for (size_t i = 0; i < k; ++i) {
      const double weight = skin.vertexWeights[v * k + i];
      if (weight == 0) continue;
      const Affine& m = matrices[skin.vertexJoints[v * k + i]];
      for (int row = 0; row < 3; ++row) {
        for (int column = 0; column < 3; ++column) blended.linear[row][column] += weight * m.linear[row][column];
      }
      blended.offset = Add(blended.offset, Scaled(m.offset, weight));
    }
    out.positions[v] = Add(blended.Apply(out.positions[v]), skin.worldOffset);
    if (!out.normals.empty()) {
      // Normals by the cofactor matrix (transform.h): their length is of no matter.
      double cofactor[3][3];
      Cofactor(blended.linear, cofactor);
      out.normals[v] = ApplyMatrix(cofactor, out.normals[v]);
    }
  }
}

}  // namespace

AnimatedWeights AnimatedWeights::Constant(std::vector<double> values) {
  AnimatedWeights weights;
  weights.constant_ = std::move(values);
  return weights;
}

AnimatedWeights AnimatedWeights::Keyframes(std::vector<Keyframe> keys, Interpolation interpolation) {
  AnimatedWeights weights;
  weights.interpolation_ = interpolation;
  if (keys.size() == 1) {
    weights.constant_ = keys.front().values;
    return weights;
  }
  for (Keyframe& key : keys) {
    // A tangent left out is flat; a spline reads one per weight.
    key.inTangent.resize(key.values.size(), 0.0);
    key.outTangent.resize(key.values.size(), 0.0);
  }
  weights.keys_ = std::move(keys);
  return weights;
}

std::vector<double> AnimatedWeights::Evaluate(double frame) const {
  if (keys_.empty()) return constant_;
  const KeySpan<Keyframe> span = FindKeySpan(keys_, frame);
  const Keyframe& previous = *span.previous;
  const Keyframe& next = *span.next;
  if (span.t == 0 || interpolation_ == Interpolation::kStep) return previous.values;
  std::vector<double> values(previous.values.size());
  for (size_t i = 0; i < values.size(); ++i) {
    values[i] = interpolation_ == Interpolation::kCubicSpline
                    ? Hermite(previous.values[i], previous.outTangent[i], next.values[i], next.inTangent[i],
                              next.frame - previous.frame, span.t)
                    : Lerp(previous.values[i], next.values[i], span.t);
  }
  return values;
}

bool AnimatedWeights::IsAnimated() const {
  for (const Keyframe& key : keys_) {
    if (key.values != keys_.front().values) return true;
    // A curve through equal keys still moves between them when it leaves with a slope.
    if (interpolation_ == Interpolation::kCubicSpline) {
      for (const auto* tangents : {&key.inTangent, &key.outTangent}) {
        for (double tangent : *tangents) {
          if (tangent != 0) return true;
        }
      }
    }
  }
  return false;
}

std::vector<Affine> SkinMatrices(const Skin& skin, double frame) {
  std::vector<Affine> matrices;
  matrices.reserve(skin.joints.size());
  for (size_t j = 0; j < skin.joints.size(); ++j) {
    matrices.push_back(Compose(skin.joints[j].WorldFromObject(frame), skin.inverseBind[j]));
  }
  return matrices;
}

bool Skin::SameAt(double a, double b) const {
  for (const Motion& joint : joints) {
    if (!joint.SameAt(a, b)) return false;
  }
  return true;
}

bool Skin::IsAnimated() const {
  for (const Motion& joint : joints) {
    if (joint.IsAnimated()) return true;
  }
  return false;
}

bool Deformation::SameAt(double a, double b) const {
  return EvaluateDeformation(*this, a) == EvaluateDeformation(*this, b);
}

DeformationAt EvaluateDeformation(const Deformation& deformation, double frame) {
  DeformationAt at;
  if (deformation.hasSkin) at.skinMatrices = SkinMatrices(deformation.skin, frame);
  if (deformation.hasMorph) at.morphWeights = deformation.morph.weights.Evaluate(frame);
  return at;
}

DeformedVertices Deform(const TriangleMesh& rest, const Deformation& deformation, double frame) {
  return Deform(rest, deformation, EvaluateDeformation(deformation, frame));
}

DeformedVertices Deform(const TriangleMesh& rest, const Deformation& deformation, const DeformationAt& at,
                        bool withNormals) {
  DeformedVertices out{rest.vertices, withNormals ? rest.normals : std::vector<Vec3>{}};
  if (deformation.hasMorph) Morph(deformation.morph, at.morphWeights, out);
  if (deformation.hasSkin) SkinVertices(deformation.skin, at.skinMatrices, out);
  return out;
}

namespace {

using TriangleIterator = std::vector<uint32_t>::iterator;

// A group is cut into at most kMaxPiecesPerGroup pieces, none cut below twice
// kTrianglesPerPiece triangles. A few cuts across a limb bring its pieces' spheres down
// to about its thickness; more add pieces for the horizons to test, each a ray meets the
// part's sphere, and take little more away. On a walking character of 50,000 triangles
// cut down to 24 triangles a piece, 1, 2, 4, 8 and 16 pieces a group left 1.35, 1.02,
// 0.92, 1.02 and 0.94 million needless traces over 48 frames (tracer_bench
// --exact-scene, ExactNeedlessTraces).
constexpr size_t kTrianglesPerPiece = 64;
constexpr size_t kMaxPiecesPerGroup = 4;

// The corners of triangles [begin, end), each once, in order.
std::vector<uint32_t> CornersOf(const TriangleMesh& mesh, TriangleIterator begin, TriangleIterator end) {
  std::vector<uint32_t> corners;
  for (auto t = begin; t != end; ++t) corners.insert(corners.end(), mesh.triangles[*t].begin(), mesh.triangles[*t].end());
  std::sort(corners.begin(), corners.end());
  corners.erase(std::unique(corners.begin(), corners.end()), corners.end());
  return corners;
}

// Triangles [begin, end) cut at the median of their centres along the longest side of
// the centres' box, and again, into at most `pieces` pieces of kTrianglesPerPiece or
// more: a limb's cuts run across it, so its pieces' bounds hug it.
void CutInPieces(const TriangleMesh& mesh, TriangleIterator begin, TriangleIterator end, size_t pieces,
                 std::vector<std::vector<uint32_t>>& out) {
  const size_t count = static_cast<size_t>(end - begin);
  if (count == 0) return;
  auto centre = [&](uint32_t t, int axis) {
    const auto& corners = mesh.triangles[t];
    return mesh.vertices[corners[0]][axis] + mesh.vertices[corners[1]][axis] + mesh.vertices[corners[2]][axis];
  };
  int longest = 0;
  double widest = -1;
  for (int axis = 0; axis < 3; ++axis) {
    double lo = INFINITY, hi = -INFINITY;
    for (auto t = begin; t != end; ++t) lo = std::min(lo, centre(*t, axis)), hi = std::max(hi, centre(*t, axis));
    if (hi - lo > widest) widest = hi - lo, longest = axis;
  }
  if (pieces <= 1 || count < 2 * kTrianglesPerPiece || !(widest > 0)) {
    out.push_back(CornersOf(mesh, begin, end));
    return;
  }
  const TriangleIterator middle = begin + static_cast<std::ptrdiff_t>(count / 2);
  std::nth_element(begin, middle, end, [&](uint32_t a, uint32_t b) {
    return centre(a, longest) < centre(b, longest) || (centre(a, longest) == centre(b, longest) && a < b);
  });
  CutInPieces(mesh, begin, middle, pieces / 2, out);
  CutInPieces(mesh, middle, end, pieces - pieces / 2, out);
}

}  // namespace

DeformationParts SplitIntoParts(const TriangleMesh& mesh, const Deformation& deformation) {
  DeformationParts parts;
  const size_t vertexCount = mesh.vertices.size();
  std::map<std::pair<std::vector<uint32_t>, std::vector<uint32_t>>, uint32_t> groupOf;
  parts.groupOfVertex.reserve(vertexCount);
  for (size_t v = 0; v < vertexCount; ++v) {
    std::vector<uint32_t> joints, targets;
    if (deformation.hasSkin) {
      const Skin& skin = deformation.skin;
      const size_t k = static_cast<size_t>(skin.influencesPerVertex);
      for (size_t i = 0; i < k; ++i) {
        if (skin.vertexWeights[v * k + i] != 0) joints.push_back(skin.vertexJoints[v * k + i]);
      }
    }
    if (deformation.hasMorph) {
      const MorphTargets& morph = deformation.morph;
      for (size_t t = 0; t < morph.TargetCount(); ++t) {
        const bool moves = morph.positionDeltas[t][v] != Vec3{} ||
                           (!morph.normalDeltas[t].empty() && morph.normalDeltas[t][v] != Vec3{});
        if (moves) targets.push_back(static_cast<uint32_t>(t));
      }
    }
    std::sort(joints.begin(), joints.end());
    joints.erase(std::unique(joints.begin(), joints.end()), joints.end());
    auto [entry, isNew] = groupOf.try_emplace({joints, targets}, static_cast<uint32_t>(parts.groups.size()));
    if (isNew) parts.groups.push_back({std::move(joints), std::move(targets), {}, {}});
    parts.groupOfVertex.push_back(entry->second);
  }
  std::vector<std::vector<uint32_t>> trianglesOf(parts.groups.size());
  for (uint32_t t = 0; t < mesh.triangles.size(); ++t) {
    for (uint32_t corner : mesh.triangles[t]) {
      std::vector<uint32_t>& triangles = trianglesOf[parts.groupOfVertex[corner]];
      if (triangles.empty() || triangles.back() != t) triangles.push_back(t);
    }
  }
  for (size_t g = 0; g < parts.groups.size(); ++g) {
    DeformationParts::Group& group = parts.groups[g];
    group.reach = CornersOf(mesh, trianglesOf[g].begin(), trianglesOf[g].end());
    CutInPieces(mesh, trianglesOf[g].begin(), trianglesOf[g].end(), kMaxPiecesPerGroup, group.pieces);
  }
  return parts;
}

std::vector<DeformationProblem> CheckDeformation(const Deformation& deformation, size_t vertexCount) {
  std::vector<DeformationProblem> problems;
  auto problem = [&](std::string where, std::string what, std::string expected) {
    problems.push_back({std::move(where), std::move(what), std::move(expected)});
  };
  if (deformation.hasMorph) {
    const MorphTargets& morph = deformation.morph;
    const std::string vertices = std::to_string(vertexCount) + " (one per vertex of the mesh)";
    for (size_t t = 0; t < morph.TargetCount(); ++t) {
      const std::string at = "/morph/targets/" + std::to_string(t);
      if (morph.positionDeltas[t].size() != vertexCount) {
        problem(at + "/positions", std::to_string(morph.positionDeltas[t].size()) + " position deltas", vertices);
      }
      if (!morph.normalDeltas[t].empty() && morph.normalDeltas[t].size() != vertexCount) {
        problem(at + "/normals", std::to_string(morph.normalDeltas[t].size()) + " normal deltas", vertices);
      }
    }
    if (morph.weights.size() != morph.TargetCount()) {
      problem("/morph/weights", std::to_string(morph.weights.size()) + " weights",
              std::to_string(morph.TargetCount()) + " (one per morph target)");
    }
  }
  if (deformation.hasSkin) {
    const Skin& skin = deformation.skin;
    const size_t k = static_cast<size_t>(skin.influencesPerVertex);
    if (skin.inverseBind.size() != skin.joints.size()) {
      problem("/skin/inverse_bind_matrices", std::to_string(skin.inverseBind.size()) + " matrices",
              std::to_string(skin.joints.size()) + " (one per joint)");
    }
    if (skin.vertexJoints.size() != vertexCount * k || skin.vertexWeights.size() != vertexCount * k) {
      problem("/skin/vertex_weights", std::to_string(skin.vertexJoints.size()) + " joint indices and " +
                           std::to_string(skin.vertexWeights.size()) + " weights",
              std::to_string(vertexCount * k) + " of each (" + std::to_string(k) + " per vertex)");
      return problems;
    }
    for (size_t v = 0; v < vertexCount; ++v) {
      double sum = 0;
      for (size_t i = 0; i < k; ++i) {
        const double weight = skin.vertexWeights[v * k + i];
        if (!(weight >= 0)) {
          problem("/skin/vertex_weights/" + std::to_string(v), "weight " + std::to_string(weight), "weights >= 0");
          return problems;
        }
        if (weight > 0 && skin.vertexJoints[v * k + i] >= skin.joints.size()) {
          problem("/skin/vertex_joints/" + std::to_string(v),
                  "joint index " + std::to_string(skin.vertexJoints[v * k + i]) + " with weight " +
                      std::to_string(weight),
                  "joint indices below " + std::to_string(skin.joints.size()) + " (the skin's joint count)");
          return problems;
        }
        sum += weight;
      }
      if (std::fabs(sum - 1) > kWeightSumTolerance) {
        problem("/skin/vertex_weights/" + std::to_string(v), "weights summing to " + std::to_string(sum),
                "weights summing to 1 (within " + std::to_string(kWeightSumTolerance) + ")");
        return problems;
      }
    }
  }
  return problems;
}

}  // namespace tcfarm
