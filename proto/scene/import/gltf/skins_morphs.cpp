// Skins and morph targets: a primitive's deformation.
#include "proto/scene/import/gltf/gltf_reader.h"

namespace tcfarm::gltf {

size_t GltfReader::MorphTargetCount(size_t node) const {
  const int meshIndex = model_.nodes[node].mesh;
  if (meshIndex < 0) return 0;
  if (static_cast<size_t>(meshIndex) >= model_.meshes.size()) {
    Fail(Pointer("nodes", node) + "/mesh", "mesh " + std::to_string(meshIndex) + " does not exist",
         "the index of a mesh");
  }
  const tinygltf::Mesh& mesh = model_.meshes[static_cast<size_t>(meshIndex)];
  const std::string pointer = Pointer("meshes", static_cast<size_t>(meshIndex));
  const size_t targets = mesh.primitives.empty() ? 0 : mesh.primitives[0].targets.size();
  for (size_t p = 1; p < mesh.primitives.size(); ++p) {
    if (mesh.primitives[p].targets.size() != targets) {
      Fail(pointer + "/primitives/" + std::to_string(p) + "/targets",
           std::to_string(mesh.primitives[p].targets.size()) + " morph targets where primitive 0 has " +
               std::to_string(targets),
           "the same number of morph targets in every primitive of a mesh");
    }
  }
  CheckWeights(mesh.weights, targets, pointer + "/weights");
  return targets;
}

void GltfReader::CheckWeights(const std::vector<double>& weights, size_t targets, const std::string& pointer) const {
  if (weights.empty()) return;
  if (weights.size() != targets) {
    Fail(pointer, std::to_string(weights.size()) + " weights for " + std::to_string(targets) + " morph targets",
         "one weight per morph target");
  }
  for (size_t i = 0; i < weights.size(); ++i) {
    if (!(std::fabs(weights[i]) <= kMaxMagnitude)) {
      Fail(pointer + "/" + std::to_string(i), std::to_string(weights[i]), "finite weights");
    }
  }
}

AnimatedWeights GltfReader::MorphWeights(size_t node, size_t targets) const {
  const tinygltf::Node& source = model_.nodes[node];
  const tinygltf::Mesh& mesh = model_.meshes[static_cast<size_t>(source.mesh)];
  CheckWeights(source.weights, targets, Pointer("nodes", node) + "/weights");
  if (auto found = channels_[node].find("weights"); found != channels_[node].end()) {
    const Channel& channel = found->second;
    const bool cubic = channel.interpolation == Interpolation::kCubicSpline;
    const double fps = options_.framesPerSecond;
    auto values = [&](size_t element) {
      auto first = channel.values.values.begin() + static_cast<std::ptrdiff_t>(element * targets);
      return std::vector<double>(first, first + static_cast<std::ptrdiff_t>(targets));
    };
    std::vector<AnimatedWeights::Keyframe> keys;
    for (size_t k = 0; k < channel.times.size(); ++k) {
      AnimatedWeights::Keyframe key{channel.times[k], values(cubic ? 3 * k + 1 : k)};
      if (cubic) {
        // glTF's tangents are per second; the scene's per frame.
        key.inTangent = values(3 * k);
        key.outTangent = values(3 * k + 2);
        for (double& tangent : key.inTangent) tangent /= fps;
        for (double& tangent : key.outTangent) tangent /= fps;
      }
      keys.push_back(std::move(key));
    }
    return AnimatedWeights::Keyframes(std::move(keys), channel.interpolation);
  }
  const std::vector<double>& weights = source.weights.empty() ? mesh.weights : source.weights;
  return AnimatedWeights::Constant(weights.empty() ? std::vector<double>(targets, 0.0) : weights);
}

MorphTargets GltfReader::ReadMorphTargets(const tinygltf::Primitive& primitive, const std::string& pointer,
                              const TriangleMesh& mesh) const {
  MorphTargets morph;
  const size_t vertices = mesh.vertices.size();
  auto deltas = [&](int accessor, const std::string& at, const std::vector<int>& componentTypes,
                    const std::string& what) {
    AccessorData data = ReadAccessor(accessor, at, {TINYGLTF_TYPE_VEC3}, componentTypes,
                                     "a VEC3 accessor of " + what);
    CheckFinite(data, accessor, what);
    if (data.count != vertices) {
      Fail(Pointer("accessors", static_cast<size_t>(accessor)) + "/count",
           std::to_string(data.count) + " " + what + " for a primitive of " + std::to_string(vertices) + " vertices",
           "one per vertex of the primitive");
    }
    std::vector<Vec3> out(vertices);
    for (size_t v = 0; v < vertices; ++v) out[v] = {data.At(v, 0), data.At(v, 1), data.At(v, 2)};
    return out;
  };
  // Floats, or KHR_mesh_quantization's signed integers.
  const std::vector<int> deltaTypes = {TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_BYTE,
                                       TINYGLTF_COMPONENT_TYPE_SHORT};
  for (size_t t = 0; t < primitive.targets.size(); ++t) {
    const auto& target = primitive.targets[t];
    const std::string at = pointer + "/targets/" + std::to_string(t);
    auto position = target.find("POSITION");
    morph.positionDeltas.push_back(position == target.end()
                                       ? std::vector<Vec3>(vertices)
                                       : deltas(position->second, at + "/POSITION", deltaTypes, "position deltas"));
    auto normal = target.find("NORMAL");
    morph.normalDeltas.push_back(normal == target.end() || mesh.normals.empty()
                                     ? std::vector<Vec3>{}
                                     : deltas(normal->second, at + "/NORMAL", deltaTypes, "normal deltas"));
  }
  return morph;
}

const GltfReader::SkinJoints& GltfReader::ReadSkin(size_t node) {
  const int index = model_.nodes[node].skin;
  if (static_cast<size_t>(index) >= model_.skins.size()) {
    Fail(Pointer("nodes", node) + "/skin",
         "skin " + std::to_string(index) + " does not exist (the file has " + std::to_string(model_.skins.size()) +
             ")",
         "the index of a skin");
  }
  auto [entry, isNew] = skins_.try_emplace(static_cast<size_t>(index));
  if (!isNew) return entry->second;
  const tinygltf::Skin& skin = model_.skins[static_cast<size_t>(index)];
  const std::string pointer = Pointer("skins", static_cast<size_t>(index));
  if (skin.joints.empty() || skin.joints.size() > kMaxJoints) {
    Fail(pointer + "/joints", std::to_string(skin.joints.size()) + " joints",
         "1 to " + std::to_string(kMaxJoints) + " joints");
  }
  auto inScene = [&](int node, const std::string& at, const std::string& what) {
    if (node < 0 || static_cast<size_t>(node) >= model_.nodes.size()) {
      Fail(at, what + " names node " + std::to_string(node) + ", which does not exist (the file has " +
                   std::to_string(model_.nodes.size()) + ")",
           "the index of a node of the rendered scene");
    }
    if (!inScene_[static_cast<size_t>(node)]) {
      Fail(at, what + " names node " + std::to_string(node) + ", which is not in the rendered scene",
           "a node of the rendered scene");
    }
  };
  if (skin.skeleton >= 0) inScene(skin.skeleton, pointer + "/skeleton", "the skeleton");
  SkinJoints& out = entry->second;
  for (size_t j = 0; j < skin.joints.size(); ++j) {
    const int joint = skin.joints[j];
    const std::string at = pointer + "/joints/" + std::to_string(j);
    inScene(joint, at, "joint " + std::to_string(j));
    if (skin.skeleton >= 0) {
      int up = joint;
      while (up >= 0 && up != skin.skeleton) up = parent_[static_cast<size_t>(up)];
      if (up != skin.skeleton) {
        Fail(at, "joint " + std::to_string(j) + " (node " + std::to_string(joint) +
                     ") is not the skeleton node " + std::to_string(skin.skeleton) + " or below it",
             "joints in the hierarchy under the skin's skeleton");
      }
    }
    out.joints.push_back(*motions_[static_cast<size_t>(joint)]);
  }
  out.inverseBind.assign(skin.joints.size(), Affine{});  // none given: identities
  if (skin.inverseBindMatrices >= 0) {
    AccessorData matrices = ReadAccessor(skin.inverseBindMatrices, pointer + "/inverseBindMatrices",
                                         {TINYGLTF_TYPE_MAT4}, {TINYGLTF_COMPONENT_TYPE_FLOAT},
                                         "a MAT4 FLOAT accessor of inverse bind matrices");
    const std::string at = Pointer("accessors", static_cast<size_t>(skin.inverseBindMatrices));
    CheckFinite(matrices, skin.inverseBindMatrices, "matrix");
    if (matrices.count != skin.joints.size()) {
      Fail(at + "/count",
           std::to_string(matrices.count) + " inverse bind matrices for " + std::to_string(skin.joints.size()) +
               " joints",
           "one per joint");
    }
    for (size_t j = 0; j < matrices.count; ++j) {
      // Column-major: element (row, column) is at 4 * column + row.
      auto m = [&](int row, int column) { return matrices.At(j, 4 * column + row); };
      if (m(3, 0) != 0 || m(3, 1) != 0 || m(3, 2) != 0 || m(3, 3) != 1) {
        Fail(at, "matrix " + std::to_string(j) + " has the last row " + Row(m(3, 0), m(3, 1), m(3, 2), m(3, 3)),
             "affine matrices (last row 0, 0, 0, 1)");
      }
      Affine& affine = out.inverseBind[j];
      for (int row = 0; row < 3; ++row) {
        for (int column = 0; column < 3; ++column) affine.linear[row][column] = m(row, column);
        affine.offset[row] = m(row, 3);
      }
    }
  }
  return out;
}

std::string GltfReader::Row(double a, double b, double c, double d) {
  std::string text;
  for (double v : {a, b, c, d}) text += (text.empty() ? "" : ", ") + nlohmann::json(v).dump();
  return text;
}

Skin GltfReader::BindPrimitive(const SkinJoints& joints, size_t node, const tinygltf::Primitive& primitive,
                   const std::string& pointer, size_t vertices) const {
  struct Set {
    AccessorData joints, weights;
    int jointsAccessor, weightsAccessor;
  };
  std::vector<Set> sets;
  for (int set = 0; set < 2; ++set) {
    const std::string suffix = "_" + std::to_string(set);
    auto jointAttribute = primitive.attributes.find("JOINTS" + suffix);
    auto weightAttribute = primitive.attributes.find("WEIGHTS" + suffix);
    const bool hasJoints = jointAttribute != primitive.attributes.end();
    const bool hasWeights = weightAttribute != primitive.attributes.end();
    if (!hasJoints && !hasWeights && set == 1) break;
    if (!hasJoints || !hasWeights) {
      Fail(pointer + "/attributes",
           std::string(hasJoints ? "JOINTS" : hasWeights ? "WEIGHTS" : "neither JOINTS nor WEIGHTS") +
               (hasJoints || hasWeights ? suffix + " alone" : suffix) + ", though node " + std::to_string(node) +
               " binds the mesh to skin " + std::to_string(model_.nodes[node].skin),
           "JOINTS_0 and WEIGHTS_0 (and JOINTS_1 with WEIGHTS_1, or neither) on each primitive of a skinned mesh");
    }
    Set read{ReadAccessor(jointAttribute->second, pointer + "/attributes/JOINTS" + suffix, {TINYGLTF_TYPE_VEC4},
                          {TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT},
                          "a VEC4 accessor of UNSIGNED_BYTE or UNSIGNED_SHORT joint indices"),
             ReadAccessor(weightAttribute->second, pointer + "/attributes/WEIGHTS" + suffix, {TINYGLTF_TYPE_VEC4},
                          {TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE,
                           TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT},
                          "a VEC4 accessor of FLOAT or normalized UNSIGNED_BYTE or UNSIGNED_SHORT weights"),
             jointAttribute->second, weightAttribute->second};
    for (const auto& [accessor, count] :
         {std::pair{read.jointsAccessor, read.joints.count}, std::pair{read.weightsAccessor, read.weights.count}}) {
      if (count != vertices) {
        Fail(Pointer("accessors", static_cast<size_t>(accessor)) + "/count",
             std::to_string(count) + " elements for a primitive of " + std::to_string(vertices) + " vertices",
             "one per vertex of the primitive");
      }
    }
    const tinygltf::Accessor& weightAccessor = model_.accessors[static_cast<size_t>(read.weightsAccessor)];
    if (weightAccessor.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT && !weightAccessor.normalized) {
      Fail(Pointer("accessors", static_cast<size_t>(read.weightsAccessor)) + "/normalized",
           "integer weights that are not normalized", "normalized: true on integer weights");
    }
    CheckFinite(read.weights, read.weightsAccessor, "vertex");
    sets.push_back(std::move(read));
  }
  Skin skin;
  skin.influencesPerVertex = static_cast<int>(4 * sets.size());
  const size_t k = static_cast<size_t>(skin.influencesPerVertex);
  skin.vertexJoints.resize(vertices * k);
  skin.vertexWeights.resize(vertices * k);
  std::vector<bool> used(joints.joints.size(), false);
  WeightFixes fixes;
  for (size_t v = 0; v < vertices; ++v) {
    double sum = 0;
    for (size_t i = 0; i < k; ++i) {
      const Set& set = sets[i / 4];
      const double joint = set.joints.At(v, static_cast<int>(i % 4));
      const double weight = set.weights.At(v, static_cast<int>(i % 4));
      if (!(weight >= 0)) {
        Fail(Pointer("accessors", static_cast<size_t>(set.weightsAccessor)),
             "vertex " + std::to_string(v) + " has the weight " + nlohmann::json(weight).dump(), "weights >= 0");
      }
      skin.vertexWeights[v * k + i] = weight;
      sum += weight;
      if (!(joint < static_cast<double>(joints.joints.size()))) {
        if (weight != 0) {
          Fail(Pointer("accessors", static_cast<size_t>(set.jointsAccessor)),
               "vertex " + std::to_string(v) + " names joint " + std::to_string(static_cast<uint64_t>(joint)) +
                   " (weight " + nlohmann::json(weight).dump() + ") of skin " +
                   std::to_string(model_.nodes[node].skin) + ", which has " + std::to_string(joints.joints.size()),
               "joint indices below the skin's joint count (or a weight of 0)");
        }
        fixes.IgnoreJoint(set.jointsAccessor, v);
      }
      if (weight == 0) continue;  // its joint does not move the vertex: index 0 will do
      used[static_cast<size_t>(joint)] = true;
      skin.vertexJoints[v * k + i] = static_cast<uint32_t>(joint);
    }
    if (sum == 0) {
      Fail(Pointer("accessors", static_cast<size_t>(sets[0].weightsAccessor)),
           "vertex " + std::to_string(v) + "'s weights are all 0" + (sets.size() > 1 ? " (with WEIGHTS_1)" : ""),
           "a positive weight on every vertex of a skinned primitive");
    }
    // Exactly 1 keeps its bits; any other sum is divided out, as glTF viewers do.
    if (sum != 1) {
      for (size_t i = 0; i < k; ++i) skin.vertexWeights[v * k + i] /= sum;
    }
    fixes.Renormalise(sum, v);
  }
  WarnOfWeightFixes(fixes, sets[0].weightsAccessor, node, vertices);
  std::vector<uint32_t> renumbered(used.size(), 0);  // per joint of the skin, its index here
  for (size_t j = 0; j < used.size(); ++j) {
    if (!used[j]) continue;
    renumbered[j] = static_cast<uint32_t>(skin.joints.size());
    skin.joints.push_back(joints.joints[j]);
    skin.inverseBind.push_back(joints.inverseBind[j]);
  }
  for (size_t i = 0; i < skin.vertexJoints.size(); ++i) {
    skin.vertexJoints[i] = renumbered[skin.vertexJoints[i]];
  }
  return skin;
}

void GltfReader::WeightFixes::Renormalise(double sum, size_t vertex) {
  if (!(std::fabs(sum - 1) > kWeightSumTolerance)) return;
  ++renormalised;
  if (std::fabs(sum - 1) > std::fabs(furthestSum - 1)) {
    furthestSum = sum;
    furthestVertex = vertex;
  }
}

void GltfReader::WeightFixes::IgnoreJoint(int jointsAccessor, size_t vertex) {
  if (ignoredJoints++ > 0) return;
  ignoredJointsAccessor = jointsAccessor;
  firstIgnoredVertex = vertex;
}

void GltfReader::WarnOfWeightFixes(const WeightFixes& fixes, int weightsAccessor, size_t node,
                                   size_t vertices) const {
  if (fixes.renormalised > 0) {
    char sum[32];
    std::snprintf(sum, sizeof sum, "%.4g", fixes.furthestSum);
    Warn("weights_renormalised", Pointer("accessors", static_cast<size_t>(weightsAccessor)),
         std::to_string(fixes.renormalised) + " of " + std::to_string(vertices) +
             " vertices have weights that do not sum to 1 (vertex " + std::to_string(fixes.furthestVertex) +
             "'s sum to " + sum + ", the furthest); each vertex's weights are divided by their sum");
  }
  if (fixes.ignoredJoints > 0) {
    Warn("joint_index_ignored", Pointer("accessors", static_cast<size_t>(fixes.ignoredJointsAccessor)),
         std::to_string(fixes.ignoredJoints) + " influences of weight 0 name joints past the " +
             std::to_string(model_.skins[static_cast<size_t>(model_.nodes[node].skin)].joints.size()) +
             " of skin " + std::to_string(model_.nodes[node].skin) + " (the first at vertex " +
             std::to_string(fixes.firstIgnoredVertex) + "); they are ignored");
  }
}

std::shared_ptr<const Deformation> GltfReader::PrimitiveDeformation(size_t node, const SkinJoints* skin,
                                                        const tinygltf::Primitive& primitive,
                                                        const std::string& pointer, const TriangleMesh& mesh) const {
  if (primitive.targets.empty() && skin == nullptr) return nullptr;
  auto deformation = std::make_shared<Deformation>();
  if (!primitive.targets.empty()) {
    deformation->hasMorph = true;
    deformation->morph = ReadMorphTargets(primitive, pointer, mesh);
    deformation->morph.weights = MorphWeights(node, primitive.targets.size());
  }
  if (skin != nullptr) {
    deformation->hasSkin = true;
    deformation->skin = BindPrimitive(*skin, node, primitive, pointer, mesh.vertices.size());
  }
  return deformation;
}

}  // namespace tcfarm::gltf
