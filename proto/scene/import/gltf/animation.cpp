// The node graph, node transforms, and the chosen animation's channels as motions.
#include "proto/scene/import/gltf/gltf_reader.h"

namespace tcfarm::gltf {

void GltfReader::BuildGraph() {
  const size_t count = model_.nodes.size();
  parent_.assign(count, -1);
  for (size_t i = 0; i < count; ++i) {
    const auto& children = model_.nodes[i].children;
    for (size_t k = 0; k < children.size(); ++k) {
      int child = children[k];
      std::string pointer = Pointer("nodes", i) + "/children/" + std::to_string(k);
      if (child < 0 || static_cast<size_t>(child) >= count) {
        Fail(pointer,
             "node " + std::to_string(child) + " does not exist (the file has " + std::to_string(count) + ")",
             "the index of a node");
      }
      if (static_cast<size_t>(child) == i)
        Fail(pointer, "node " + std::to_string(i) + " is its own child", "a tree of nodes");
      if (parent_[static_cast<size_t>(child)] >= 0) {
        Fail(pointer,
             "node " + std::to_string(child) + " already has parent " +
                 std::to_string(parent_[static_cast<size_t>(child)]),
             "a tree of nodes: each node the child of at most one");
      }
      parent_[static_cast<size_t>(child)] = static_cast<int>(i);
    }
  }
  // With one parent each, a cycle is a walk up that comes back.
  for (size_t i = 0; i < count; ++i) {
    size_t steps = 0;
    for (int up = parent_[i]; up >= 0; up = parent_[static_cast<size_t>(up)]) {
      if (static_cast<size_t>(up) == i || ++steps > count) {
        Fail(Pointer("nodes", i), "node " + std::to_string(i) + " is its own ancestor (a recursive node graph)",
             "a tree of nodes");
      }
    }
  }
  std::vector<int> roots;
  // "scene" must name a scene even in a file without any.
  if (model_.defaultScene >= 0 && static_cast<size_t>(model_.defaultScene) >= model_.scenes.size()) {
    Fail("/scene",
         "scene " + std::to_string(model_.defaultScene) + " does not exist (the file has " +
             std::to_string(model_.scenes.size()) + " scenes)",
         "the index of a scene");
  }
  if (!model_.scenes.empty()) {
    size_t chosen = model_.defaultScene >= 0 ? static_cast<size_t>(model_.defaultScene) : 0;
    const auto& nodes = model_.scenes[chosen].nodes;
    for (size_t k = 0; k < nodes.size(); ++k) {
      std::string pointer = Pointer("scenes", chosen) + "/nodes/" + std::to_string(k);
      if (nodes[k] < 0 || static_cast<size_t>(nodes[k]) >= count) {
        Fail(pointer, "node " + std::to_string(nodes[k]) + " does not exist", "the index of a node");
      }
      if (parent_[static_cast<size_t>(nodes[k])] >= 0)
        Fail(pointer, "node " + std::to_string(nodes[k]) + " has a parent", "a root node");
      roots.push_back(nodes[k]);
    }
  } else {
    // No scene: every root node, as viewers do.
    for (size_t i = 0; i < count; ++i) {
      if (parent_[i] < 0) roots.push_back(static_cast<int>(i));
    }
  }
  // Depth-first, so parents come before their children.
  std::vector<int> stack(roots.rbegin(), roots.rend());
  inScene_.assign(count, false);
  while (!stack.empty()) {
    int node = stack.back();
    stack.pop_back();
    if (inScene_[static_cast<size_t>(node)]) continue;
    inScene_[static_cast<size_t>(node)] = true;
    order_.push_back(node);
    const auto& children = model_.nodes[static_cast<size_t>(node)].children;
    for (auto it = children.rbegin(); it != children.rend(); ++it) stack.push_back(*it);
  }
}

void GltfReader::Decompose(const std::vector<double>& m, const std::string& pointer, Vec3* translation, Quaternion* rotation,
               Vec3* scale) const {
  for (double v : m) {
    if (!(std::fabs(v) <= kMaxMagnitude)) Fail(pointer, "a matrix element of " + std::to_string(v), "finite numbers");
  }
  if (m[3] != 0 || m[7] != 0 || m[11] != 0 || m[15] != 1) {
    Fail(pointer, "a projective bottom row", "an affine matrix (bottom row 0, 0, 0, 1)");
  }
  Vec3 column[3] = {{m[0], m[1], m[2]}, {m[4], m[5], m[6]}, {m[8], m[9], m[10]}};
  double length[3] = {Norm(column[0]), Norm(column[1]), Norm(column[2])};
  double longest = std::max({length[0], length[1], length[2]});
  if (!(longest > 0) || std::min({length[0], length[1], length[2]}) <= kSingularRatio * longest) {
    Fail(pointer, "a singular matrix", "a matrix of translation, rotation and non-zero scale");
  }
  Vec3 cross = CrossProduct(column[0], column[1]);
  double determinant = cross.x * column[2].x + cross.y * column[2].y + cross.z * column[2].z;
  // A mirror is a negative scale on x.
  if (determinant < 0) length[0] = -length[0];
  double r[3][3];
  for (int c = 0; c < 3; ++c) {
    for (int row = 0; row < 3; ++row) r[row][c] = column[c][row] / length[c];
  }
  for (int a = 0; a < 3; ++a) {
    for (int b = 0; b < 3; ++b) {
      double dot = r[0][a] * r[0][b] + r[1][a] * r[1][b] + r[2][a] * r[2][b];
      if (std::fabs(dot - (a == b ? 1 : 0)) > kOrthonormalTolerance) {
        Fail(pointer, "a matrix with shear", "a matrix of translation, rotation and scale only");
      }
    }
  }
  *translation = {m[12], m[13], m[14]};
  *scale = {length[0], length[1], length[2]};
  // Shepperd's method: divide by the largest of the four candidates.
  double trace = r[0][0] + r[1][1] + r[2][2];
  Quaternion q;
  if (trace > 0) {
    double s = std::sqrt(trace + 1) * 2;
    q = {s / 4, (r[2][1] - r[1][2]) / s, (r[0][2] - r[2][0]) / s, (r[1][0] - r[0][1]) / s};
  } else if (r[0][0] > r[1][1] && r[0][0] > r[2][2]) {
    double s = std::sqrt(1 + r[0][0] - r[1][1] - r[2][2]) * 2;
    q = {(r[2][1] - r[1][2]) / s, s / 4, (r[0][1] + r[1][0]) / s, (r[0][2] + r[2][0]) / s};
  } else if (r[1][1] > r[2][2]) {
    double s = std::sqrt(1 + r[1][1] - r[0][0] - r[2][2]) * 2;
    q = {(r[0][2] - r[2][0]) / s, (r[0][1] + r[1][0]) / s, s / 4, (r[1][2] + r[2][1]) / s};
  } else {
    double s = std::sqrt(1 + r[2][2] - r[0][0] - r[1][1]) * 2;
    q = {(r[1][0] - r[0][1]) / s, (r[0][2] + r[2][0]) / s, (r[1][2] + r[2][1]) / s, s / 4};
  }
  *rotation = q;
}

void GltfReader::ChooseAnimation() {
  animation_ = -1;
  frameCount_ = 1;
  if (!(options_.framesPerSecond > 0) || !std::isfinite(options_.framesPerSecond)) {
    Fail("", "a frame rate of " + std::to_string(options_.framesPerSecond), "a positive frames per second");
  }
  const std::string& wanted = options_.animation;
  if (wanted.empty()) {
    if (!model_.animations.empty()) animation_ = 0;
  } else {
    for (size_t i = 0; i < model_.animations.size(); ++i) {
      if (model_.animations[i].name == wanted) {
        animation_ = static_cast<int>(i);
        break;
      }
    }
    if (animation_ < 0 && wanted.find_first_not_of("0123456789") == std::string::npos && wanted.size() < 9 &&
        std::stoul(wanted) < model_.animations.size()) {
      animation_ = std::stoi(wanted);
    }
    if (animation_ < 0) {
      Fail("/animations",
           "no animation named or numbered " + QuoteInput(wanted) + " (the file has " +
               std::to_string(model_.animations.size()) + ")",
           "an animation's name or index");
    }
  }
}

std::vector<double> GltfReader::ReadTimes(int accessor, const std::string& referencedAt) const {
  AccessorData data = ReadAccessor(accessor, referencedAt, {TINYGLTF_TYPE_SCALAR}, {TINYGLTF_COMPONENT_TYPE_FLOAT},
                                   "a SCALAR FLOAT accessor of key times in seconds");
  const std::string pointer = Pointer("accessors", static_cast<size_t>(accessor));
  if (data.count == 0) Fail(pointer + "/count", "no key times", "at least one key");
  std::vector<double> frames;
  for (size_t k = 0; k < data.count; ++k) {
    double time = data.values[k];
    if (!std::isfinite(time) || time < 0) {
      Fail(pointer, "key time " + std::to_string(k) + " is " + std::to_string(time), "finite non-negative times");
    }
    double frame = time * options_.framesPerSecond;
    if (!frames.empty() && !(frame > frames.back())) {
      Fail(pointer,
           "key time " + std::to_string(k) + " (" + std::to_string(time) + " s) does not follow key " +
               std::to_string(k - 1),
           "strictly increasing key times");
    }
    frames.push_back(frame);
  }
  return frames;
}

GltfReader::Channel GltfReader::ReadChannel(const tinygltf::AnimationSampler& sampler, const std::string& samplerPointer, int type,
                    const std::vector<int>& componentTypes, const std::string& expected, size_t perKey) const {
  Channel channel;
  channel.present = true;
  channel.times = ReadTimes(sampler.input, samplerPointer + "/input");
  if (sampler.interpolation == "STEP") {
    channel.interpolation = Interpolation::kStep;
  } else if (sampler.interpolation == "CUBICSPLINE") {
    channel.interpolation = Interpolation::kCubicSpline;
  } else if (sampler.interpolation == "LINEAR" || sampler.interpolation.empty()) {
    channel.interpolation = Interpolation::kLinear;
  } else {
    Fail(samplerPointer + "/interpolation", QuoteInput(sampler.interpolation), "LINEAR, STEP or CUBICSPLINE");
  }
  channel.values = ReadAccessor(sampler.output, samplerPointer + "/output", {type}, componentTypes, expected);
  CheckFinite(channel.values, sampler.output, "key value");
  const bool cubic = channel.interpolation == Interpolation::kCubicSpline;
  const size_t wanted = channel.times.size() * perKey * (cubic ? 3 : 1);
  if (channel.values.count != wanted) {
    const std::string what = perKey > 1 ? std::to_string(perKey) + " weights (one per morph target) " : "one value ";
    Fail(Pointer("accessors", static_cast<size_t>(sampler.output)) + "/count",
         std::to_string(channel.values.count) + " values for " + std::to_string(channel.times.size()) + " key times",
         std::to_string(wanted) + " values (" + what +
             (cubic ? "per in-tangent, value and out-tangent of each key)" : "per key)"));
  }
  return channel;
}

void GltfReader::BuildMotions() {
  const size_t count = model_.nodes.size();
  channels_.assign(count, {});
  double lastFrame = 0;
  if (animation_ >= 0) {
    const auto& animation = model_.animations[static_cast<size_t>(animation_)];
    const std::string animationPointer = Pointer("animations", static_cast<size_t>(animation_));
    for (size_t c = 0; c < animation.channels.size(); ++c) {
      const auto& channel = animation.channels[c];
      const std::string pointer = animationPointer + "/channels/" + std::to_string(c);
      if (channel.target_node < 0) continue;  // a target for an extension
      if (static_cast<size_t>(channel.target_node) >= count) {
        Fail(pointer + "/target/node", "node " + std::to_string(channel.target_node) + " does not exist",
             "the index of a node");
      }
      const std::string& path = channel.target_path;
      if (path != "translation" && path != "rotation" && path != "scale" && path != "weights") {
        Fail(pointer + "/target/path", "path " + QuoteInput(path), "translation, rotation, scale or weights");
      }
      if (channel.sampler < 0 || static_cast<size_t>(channel.sampler) >= animation.samplers.size()) {
        Fail(pointer + "/sampler", "sampler " + std::to_string(channel.sampler) + " does not exist",
             "the index of a sampler");
      }
      const auto& node = model_.nodes[static_cast<size_t>(channel.target_node)];
      if (!node.matrix.empty()) {
        Fail(pointer + "/target/node", "node " + std::to_string(channel.target_node) + " has a matrix",
             "animated nodes with translation, rotation and scale (the glTF rule)");
      }
      Channel& target = channels_[static_cast<size_t>(channel.target_node)][path];
      if (target.present)
        Fail(pointer, "a second channel for " + path + " of the same node", "one channel per node and path");
      const std::string samplerPointer = animationPointer + "/samplers/" + std::to_string(channel.sampler);
      const auto& sampler = animation.samplers[static_cast<size_t>(channel.sampler)];
      // Rotations and weights may be floats or normalized integers.
      const std::vector<int> floatsOrIntegers = {
          TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_BYTE, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE,
          TINYGLTF_COMPONENT_TYPE_SHORT, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT};
      if (path == "weights") {
        const size_t targets = MorphTargetCount(static_cast<size_t>(channel.target_node));
        if (targets == 0) {
          Fail(pointer + "/target/node",
               "node " + std::to_string(channel.target_node) + " has no mesh with morph targets",
               "a weights channel on a node whose mesh has morph targets");
        }
        target = ReadChannel(sampler, samplerPointer, TINYGLTF_TYPE_SCALAR, floatsOrIntegers,
                             "a SCALAR accessor of morph target weights", targets);
      } else if (path == "rotation") {
        target = ReadChannel(sampler, samplerPointer, TINYGLTF_TYPE_VEC4, floatsOrIntegers,
                             "a VEC4 accessor of quaternions", 1);
      } else {
        target = ReadChannel(sampler, samplerPointer, TINYGLTF_TYPE_VEC3, {TINYGLTF_COMPONENT_TYPE_FLOAT},
                             "a VEC3 FLOAT accessor", 1);
      }
      lastFrame = std::max(lastFrame, target.times.back());
    }
  }
  double frames = std::ceil(lastFrame);
  if (frames + 1 > kMaxFrameCount) {
    Fail(Pointer("animations", static_cast<size_t>(animation_)),
         "the animation lasts " + std::to_string(lastFrame / options_.framesPerSecond) + " s, " +
             std::to_string(frames + 1) + " frames at " + std::to_string(options_.framesPerSecond) + " per second",
         "at most " + std::to_string(kMaxFrameCount) + " frames");
  }
  frameCount_ = static_cast<int>(frames) + 1;

  motions_.assign(count, nullptr);
  for (int node : order_) {
    auto motion =
        std::make_shared<Motion>(LocalMotion(static_cast<size_t>(node), channels_[static_cast<size_t>(node)]));
    int parent = parent_[static_cast<size_t>(node)];
    if (parent >= 0 && !motions_[static_cast<size_t>(parent)]->IsNone()) {
      motion->parent = motions_[static_cast<size_t>(parent)];
    }
    int depth = 0;
    for (const Motion* up = motion.get(); up->parent; up = up->parent.get()) ++depth;
    if (depth >= kMaxMotionDepth) {
      Fail(Pointer("nodes", static_cast<size_t>(node)), "a node " + std::to_string(depth) + " levels deep",
           "a hierarchy at most " + std::to_string(kMaxMotionDepth) + " levels deep");
    }
    motions_[static_cast<size_t>(node)] = motion;
  }
}

int GltfReader::FramesAsked() const {
  const int last = options_.lastFrame;
  if (last < frameCount_) return frameCount_;
  if (last >= kMaxFrameCount) {
    Fail("", "frames up to " + std::to_string(last) + " asked for",
         "at most " + std::to_string(kMaxFrameCount) + " frames");
  }
  // Every animated value is held after its last key (proto/scene/transform.h), as Blender
  // and glTF viewers hold it: the frames past the end are the last frame again, and the
  // scene's range covers them so that they are checked and rendered as its own.
  const bool one = last == frameCount_;
  const std::string frames = (one ? "frame " : "frames ") + std::to_string(frameCount_) +
                             (one ? "" : "-" + std::to_string(last));
  if (animation_ < 0) {
    Warn("frames_past_animation", "",
         "the file has no animation: " + frames + (one ? " shows" : " show") + " it as frame 0 does");
  } else {
    Warn("frames_past_animation", Pointer("animations", static_cast<size_t>(animation_)),
         frames + (one ? " holds" : " hold") + " the last key (the animation ends at frame " +
             std::to_string(frameCount_ - 1) + ")");
  }
  return last + 1;
}

Motion GltfReader::LocalMotion(size_t index, const std::map<std::string, Channel>& channels) const {
  const tinygltf::Node& node = model_.nodes[index];
  const std::string pointer = Pointer("nodes", index);
  Vec3 translation, scale{1, 1, 1};
  Quaternion rotation;
  if (!node.matrix.empty()) {
    if (node.matrix.size() != 16)
      Fail(pointer + "/matrix", std::to_string(node.matrix.size()) + " numbers", "16 numbers");
    Decompose(node.matrix, pointer + "/matrix", &translation, &rotation, &scale);
  } else {
    auto check = [&](const std::vector<double>& values, size_t size, const char* key) {
      if (!values.empty() && values.size() != size) {
        Fail(pointer + "/" + key, std::to_string(values.size()) + " numbers", std::to_string(size) + " numbers");
      }
      for (double v : values) {
        if (!(std::fabs(v) <= kMaxMagnitude))
          Fail(pointer + "/" + key, "a value of " + std::to_string(v), "finite numbers");
      }
    };
    check(node.translation, 3, "translation");
    check(node.rotation, 4, "rotation");
    check(node.scale, 3, "scale");
    if (!node.translation.empty()) translation = {node.translation[0], node.translation[1], node.translation[2]};
    if (!node.rotation.empty()) rotation = {node.rotation[3], node.rotation[0], node.rotation[1], node.rotation[2]};
    if (!node.scale.empty()) scale = {node.scale[0], node.scale[1], node.scale[2]};
  }
  if (rotation.w == 0 && rotation.x == 0 && rotation.y == 0 && rotation.z == 0) {
    Fail(pointer + "/rotation", "a zero quaternion", "a unit quaternion");
  }
  for (int axis = 0; axis < 3; ++axis) {
    if (!(std::fabs(scale[axis]) >= kMinScale && std::fabs(scale[axis]) <= kMaxScale)) {
      Fail(pointer, "a scale of " + std::to_string(scale[axis]), "scale components of magnitude in [1e-6, 1e6]");
    }
  }
  Motion motion;
  motion.translation = AnimatedVec3::Constant(translation);
  motion.rotation = AnimatedRotation::Constant(rotation);
  motion.scale = AnimatedVec3::Constant(scale);
  const double fps = options_.framesPerSecond;
  auto vectorKeys = [&](const Channel& channel) {
    std::vector<AnimatedVec3::Keyframe> keys;
    bool cubic = channel.interpolation == Interpolation::kCubicSpline;
    for (size_t k = 0; k < channel.times.size(); ++k) {
      size_t at = cubic ? 3 * k + 1 : k;
      AnimatedVec3::Keyframe key{channel.times[k],
                                 {channel.values.At(at, 0), channel.values.At(at, 1), channel.values.At(at, 2)}};
      if (cubic) {
        // glTF's tangents are per second; the scene's per frame.
        key.inTangent = {channel.values.At(at - 1, 0) / fps, channel.values.At(at - 1, 1) / fps,
                         channel.values.At(at - 1, 2) / fps};
        key.outTangent = {channel.values.At(at + 1, 0) / fps, channel.values.At(at + 1, 1) / fps,
                          channel.values.At(at + 1, 2) / fps};
      }
      keys.push_back(key);
    }
    return AnimatedVec3::Keyframes(std::move(keys), channel.interpolation);
  };
  if (auto found = channels.find("translation"); found != channels.end())
    motion.translation = vectorKeys(found->second);
  if (auto found = channels.find("scale"); found != channels.end()) {
    const Channel& channel = found->second;
    for (size_t i = 0; i < channel.values.values.size(); ++i) {
      // Only key values bound the scale (tangents may overshoot: the parser checks frames).
      bool value = channel.interpolation != Interpolation::kCubicSpline || (i / 3) % 3 == 1;
      double v = std::fabs(channel.values.values[i]);
      if (value && !(v >= kMinScale && v <= kMaxScale)) {
        Fail(pointer, "an animated scale of " + std::to_string(channel.values.values[i]),
             "scale components of magnitude in [1e-6, 1e6] (a node cannot be scaled to nothing)");
      }
    }
    motion.scale = vectorKeys(channel);
  }
  if (auto found = channels.find("rotation"); found != channels.end()) {
    const Channel& channel = found->second;
    bool cubic = channel.interpolation == Interpolation::kCubicSpline;
    std::vector<AnimatedRotation::Keyframe> keys;
    auto quaternion = [&](size_t at, double divide) {
      return Quaternion{channel.values.At(at, 3) / divide, channel.values.At(at, 0) / divide,
                        channel.values.At(at, 1) / divide, channel.values.At(at, 2) / divide};
    };
    for (size_t k = 0; k < channel.times.size(); ++k) {
      size_t at = cubic ? 3 * k + 1 : k;
      AnimatedRotation::Keyframe key{channel.times[k], quaternion(at, 1)};
      if (key.value.w == 0 && key.value.x == 0 && key.value.y == 0 && key.value.z == 0) {
        Fail(pointer, "a zero quaternion at key " + std::to_string(k) + " of its rotation channel",
             "unit quaternions");
      }
      if (cubic) {
        key.inTangent = quaternion(at - 1, fps);
        key.outTangent = quaternion(at + 1, fps);
      }
      keys.push_back(key);
    }
    motion.rotation = AnimatedRotation::Keyframes(std::move(keys), channel.interpolation);
  }
  return motion;
}

}  // namespace tcfarm::gltf
