// Whitted ray tracing of an arbitrary pixel set of an arbitrary frame.
//
// Determinism is the contract the coordinator builds on: a pixel's bits depend only on
// the scene, the frame and the pixel, never on which other pixels are traced with it,
// the thread count or the order. Sample positions are seeded by pixel (not frame), so a
// pixel that sees nothing change stays bit-identical from frame to frame.
#pragma once

#include <array>
#include <atomic>
#include <map>
#include <memory>
#include <mutex>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "worker/embree/scene_geometry.h"
#include "worker/trace/float3.h"
#include "worker/trace/materials.h"
#include "worker/trace/textures.h"
#include "proto/scene/scene.h"
#include "worker/util/tracing_threads.h"

namespace tcfarm {

// Rays cast, by type. They prove what a scene leaves out: no shadow rays without
// lights, no reflection or refraction rays without such materials.
struct RayCounts {
  uint64_t primary = 0;
  uint64_t shadow = 0;
  uint64_t reflection = 0;
  uint64_t refraction = 0;
  uint64_t Total() const { return primary + shadow + reflection + refraction; }
  RayCounts& operator+=(const RayCounts& o) {
    primary += o.primary;
    shadow += o.shadow;
    reflection += o.reflection;
    refraction += o.refraction;
    return *this;
  }
};

class Tracer {
 public:
  // The scene must outlive the tracer.
  // Throws BuildStopped once `stop` is set while it builds (util/build_stop.h).
  Tracer(const EmbreeDevice& device, const Scene& scene, TracingThreads& threads, BuildStop stop = nullptr);

  // Traces pixels (linear indices y * width + x, each < width * height) of `frame` and
  // writes 3 floats of linear RGB per pixel to `rgb`, in the order given. With window > 0
  // it also writes each pixel's validity horizon (trace/horizons.h) to `horizons`: a frame
  // in [frame + 1, frame + window + 1], the last meaning "valid through the window".
  void TracePixels(int frame, const uint32_t* pixels, size_t pixelCount, float* rgb,
                   int window = 0, int32_t* horizons = nullptr);
  // Every pixel of a frame, row by row.
  void TraceFrame(int frame, float* rgb);

  RayCounts Counts() const;
  // CPU time the tracing threads have spent in TracePixels, all threads summed. Unlike
  // elapsed time, it does not grow when other processes share the cores: the cost of a
  // task on a shared machine.
  double CpuSeconds() const { return cpuNanoseconds_ * 1e-9; }
  // Per-frame top-level scenes built (0 for a scene where nothing moves).
  uint64_t FrameBuilds() const { return geometry_.FrameBuilds(); }
  // Deforming meshes' poses and vertices (all 0 in a scene without skins or morphs).
  SceneGeometry::DeformationWork DeformationCounts() const { return geometry_.DeformationCounts(); }
  const Scene& scene() const { return scene_; }
  // Camera samples cast together as one Embree packet: 16 where Embree runs that natively,
  // else 8 (embree/ray_packets.h). Every width gives the same bits; tests set each.
  int PacketWidth() const { return packetWidth_; }
  void SetPacketWidth(int width);

  // The tracer's inside (pixel_tracer.h), named here so that a material model's shading
  // (worker/trace/materials/) can take them: what shading reads of a shape, and one
  // thread's tracer.
  struct ShapeShading;
  class PixelTracer;

 private:
  struct FrameContext;
  // Each shape's record for shading at a frame (its normals may be a pose's).
  std::vector<ShapeShading> ShadingAt(const FrameGeometry& frame) const;

  const EmbreeDevice& device_;
  const Scene& scene_;
  // Per shape, texture coordinates in float (shapes placing one shared mesh share them):
  // TEXCOORD_0's for every mesh, TEXCOORD_1's where a material reads them. Before the
  // surface rules, whose alpha masks read them too.
  using ShapeUvs = std::vector<std::array<float, 2>>;
  std::vector<std::shared_ptr<const ShapeUvs>> uvs_, uvs1_;
  static std::vector<std::shared_ptr<const ShapeUvs>> UvTable(const Scene& scene, int set);
  // The images materials read, decoded once each (by image, sampling and encoding).
  std::map<std::pair<std::string, TextureImage::Encoding>, std::unique_ptr<TextureImage>> textureImages_;
  const TextureImage* LoadTexture(const Texture& texture, TextureImage::Encoding encoding);
  // By shape, which of its hits count (alpha masks, one-sided materials): before the
  // geometry, whose filters ask them.
  std::vector<std::unique_ptr<SurfaceRule>> surfaceRules_;
  std::vector<std::unique_ptr<SurfaceRule>> MakeSurfaceRules();
  SceneGeometry geometry_;
  // Normals change with a deforming mesh's pose: the frame's geometry holds them.
  // Materials never change over frames: each made for shading once, by material.
  std::vector<ShadingMaterial> materials_;
  // Per shape, its vertices' colours (none for most shapes), shared like the uvs.
  using ShapeColors = std::vector<Float3>;
  std::vector<std::shared_ptr<const ShapeColors>> colors_;
  // Per shape, its tangents (glTF's TANGENT), where a material's normal map reads them.
  using ShapeTangents = std::vector<std::array<float, 4>>;
  std::vector<std::shared_ptr<const ShapeTangents>> tangents_;

  // Records the frame of a trace with horizons; true while the last few such traces went
  // forward frame after frame: one segment in flight.
  bool OneSegmentInFlight(int frame);
  std::mutex recentMutex_;
  std::array<int, 8> recentTracedFrames_{};
  size_t recentTraces_ = 0;

  TracingThreads& threads_;
  int packetWidth_;
  std::atomic<uint64_t> primary_{0}, shadow_{0}, reflection_{0}, refraction_{0};
  std::atomic<uint64_t> cpuNanoseconds_{0};
};

}  // namespace tcfarm
