// Deforming meshes: morph targets and skins (glTF's two ways of moving vertices).
//
// A mesh shape may carry a Deformation. Its vertices at a frame are then, in this order:
//   morphed: p = rest + sum_k weight_k(frame) * positionDelta_k (normals likewise), in the
//            mesh's own space;
//   skinned: p' = sum_i w_i * jointWorld_i(frame) * inverseBind_i * p, in world space
//            (the shape's own motion is then the identity: glTF ignores a skinned mesh
//            node's transform), offset by `worldOffset` (RebaseOnCamera's shift).
// Everything is computed in double and rounded to float once, by the tracer, so a vertex
// that the same weights and matrices place is placed to the same bits on every worker.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "proto/scene/animated_vec3.h"
#include "proto/scene/transform.h"

namespace tcfarm {

struct TriangleMesh;

// N weights over frame time (morph target weights): constant, or keyframes joined as
// glTF joins them (held before the first and after the last key).
class AnimatedWeights {
 public:
  struct Keyframe {
    double frame;
    std::vector<double> values;
    std::vector<double> inTangent = {}, outTangent = {};  // cubic spline only, per frame; absent = 0
  };

  AnimatedWeights() = default;
  static AnimatedWeights Constant(std::vector<double> values);
  // Keys sorted by frame, none on one frame twice, each with size() values (the parser checks).
  static AnimatedWeights Keyframes(std::vector<Keyframe> keys, Interpolation interpolation);

  std::vector<double> Evaluate(double frame) const;
  // True when Evaluate can return different weights for different frames.
  bool IsAnimated() const;
  size_t size() const { return keys_.empty() ? constant_.size() : keys_.front().values.size(); }

  bool IsConstant() const { return keys_.empty(); }
  const std::vector<double>& constant() const { return constant_; }
  const std::vector<Keyframe>& keys() const { return keys_; }
  Interpolation interpolation() const { return interpolation_; }

 private:
  std::vector<double> constant_;
  std::vector<Keyframe> keys_;
  Interpolation interpolation_ = Interpolation::kLinear;
};

struct MorphTargets {
  // Per target, one delta per vertex; normal deltas may be absent (empty) for a target.
  std::vector<std::vector<Vec3>> positionDeltas;
  std::vector<std::vector<Vec3>> normalDeltas;
  AnimatedWeights weights;  // one weight per target

  size_t TargetCount() const { return positionDeltas.size(); }
};

struct Skin {
  // Per joint: its node's transform to the world over frame time, and its inverse bind
  // matrix (the world-from-joint transform at bind time, inverted).
  std::vector<Motion> joints;
  std::vector<Affine> inverseBind;
  // Per vertex, influencesPerVertex (joint, weight) pairs; each vertex's weights sum to 1.
  int influencesPerVertex = 4;
  std::vector<uint32_t> vertexJoints;
  std::vector<double> vertexWeights;
  Vec3 worldOffset;  // added to every skinned vertex (RebaseOnCamera)

  // Whether the skin matrix of every joint is the same at frames a and b, bit for bit.
  bool SameAt(double a, double b) const;
  bool IsAnimated() const;
};

struct Deformation {
  bool hasMorph = false, hasSkin = false;
  MorphTargets morph;
  Skin skin;

  bool IsAnimated() const { return (hasMorph && morph.weights.IsAnimated()) || (hasSkin && skin.IsAnimated()); }
  // Whether the deformed mesh at frames a and b is the same, bit for bit: the same morph
  // weights and the same joint matrices.
  bool SameAt(double a, double b) const;
};

// A mesh's vertices and shading normals at one frame (normals empty when the mesh has
// none), in the shape's object space, or the world's for a skinned mesh.
struct DeformedVertices {
  std::vector<Vec3> positions;
  std::vector<Vec3> normals;
};

// What a deformation is at one frame: its joints' skin matrices (SkinMatrices) and its
// morph weights, each empty without a skin or morph. Two frames with equal values deform
// the mesh to the same bits.
struct DeformationAt {
  std::vector<Affine> skinMatrices;
  std::vector<double> morphWeights;
  bool operator==(const DeformationAt& o) const {
    return skinMatrices == o.skinMatrices && morphWeights == o.morphWeights;
  }
};
DeformationAt EvaluateDeformation(const Deformation& deformation, double frame);

DeformedVertices Deform(const TriangleMesh& rest, const Deformation& deformation, double frame);
// The same from the frame's values evaluated once; withNormals false leaves the normals
// out (bounds need the positions alone).
DeformedVertices Deform(const TriangleMesh& rest, const Deformation& deformation, const DeformationAt& at,
                        bool withNormals = true);

// A deforming mesh's vertices grouped by what moves them: the joints they are weighted to
// and the morph targets that move them. A group holds still while its joints' matrices
// and its targets' weights do, so the parts of a character that do not move between two
// frames are known to be still (its torso while an arm waves).
struct DeformationParts {
  struct Group {
    std::vector<uint32_t> joints, targets;  // what moves the group's vertices
    // Every vertex of every triangle that has a vertex in the group: what the group's
    // bounds must hold, since a triangle is moved by any of its corners.
    std::vector<uint32_t> reach;
    // Those triangles cut in space at rest, each piece the corners of some of them: every
    // triangle lies within the bounds of the piece that holds it, so the pieces' bounds
    // hold the group as its own bounds do, with far less empty space around a limb.
    std::vector<std::vector<uint32_t>> pieces;
  };
  std::vector<uint32_t> groupOfVertex;
  std::vector<Group> groups;
};
DeformationParts SplitIntoParts(const TriangleMesh& mesh, const Deformation& deformation);

// The skin matrices of every joint at a frame: jointWorld(frame) * inverseBind.
std::vector<Affine> SkinMatrices(const Skin& skin, double frame);

// What a skin or morph asks of the mesh, checked: a message naming what is wrong and what
// was expected, or empty. The parser and importers report it with their own pointer.
struct DeformationProblem {
  std::string where;    // a pointer suffix, relative to the deformation ("/skin/weights/3")
  std::string problem;  // what is wrong
  std::string expected;
};
std::vector<DeformationProblem> CheckDeformation(const Deformation& deformation, size_t vertexCount);

// Tolerance on a vertex's weight sum: glTF asks for 1 within about 2e-7 per weight for
// floats, more for normalized integers (1/255 per weight). A scene's skin whose sums are
// off by more is refused; the glTF importer divides every sum out and warns of those off
// by more (old exporters write sums such as 0.685), closer ones being rounding.
constexpr double kWeightSumTolerance = 2e-2;

}  // namespace tcfarm
