// The scene format's bounds (proto/scene.md, proto/scene.schema.json), in one place: the
// JSON parser, every importer and the front ends that take render settings before there is
// a scene (the HTTP API's import options, the worker's render command) all check these.
#pragma once

#include <cstddef>

namespace tcfarm::scene_limits {

// Render settings.
inline constexpr int kMaxImageSide = 16384;  // width and height alike: width * height fits a uint32 pixel index
inline constexpr int kMaxSamplesPerPixel = 1024;
inline constexpr int kMaxFirstFrame = 10'000'000;
inline constexpr int kMaxFrameCount = 100'000;
inline constexpr int kMaxBounceDepth = 64;  // max_depth: bounces after the primary hit

// Imported animations are sampled at a frame rate within these.
inline constexpr double kMinFramesPerSecond = 0.001, kMaxFramesPerSecond = 100000;

// Beyond this, squared distances in the tracer approach overflow and ray offsets lose
// all meaning; no sensible scene needs coordinates anywhere near it.
inline constexpr double kMaxMagnitude = 1e30;
// A scale component this close to 0 collapses the shape onto a plane, whose normals are
// undefined; this far from 1 the object leaves float's useful range.
inline constexpr double kMinScale = 1e-6, kMaxScale = 1e6;
inline constexpr double kMinIndexOfRefraction = 1, kMaxIndexOfRefraction = 10;
// A normal map's scale and KHR_materials_emissive_strength: generous, finite.
inline constexpr double kMaxNormalScale = 1000;
inline constexpr double kMaxEmissiveStrength = 1e6;
// Joints of one skin: far more than any character rig has (glTF's own limits are those of
// its index types), few enough that a scene's skin matrices stay small.
inline constexpr size_t kMaxJoints = 4096;
// Parents nest one object deep per level; a hierarchy deeper than this is refused (the
// JSON parser's own nesting limit is 128 levels).
inline constexpr int kMaxMotionDepth = 32;

// Keeps a single job within a worker's memory (Embree BVH plus mesh: ~100 bytes/triangle);
// every importer charges its triangles against it.
inline constexpr size_t kMaxTriangles = 20'000'000;

}  // namespace tcfarm::scene_limits
