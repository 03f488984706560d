// A real shot's load: about 100,000 triangles of smooth meshes that move and turn over a
// floor, 640x480, one point light. The tracer's time per frame beside a bare Embree loop
// over the very same triangles and placements (8-wide primary packets, one shadow ray,
// Lambert with Embree's own normals): the price of everything the tracer adds (exact
// normals, smooth shading, ties, horizons bookkeeping, ray counting).
//   build/worker/mesh_bench [--benchmark_min_time=2]
#include <benchmark/benchmark.h>

#include <malloc.h>

#include <cmath>
#include <string>
#include <vector>

#include "embree/device.h"
#include "scene/scene.h"
#include "trace/tracer.h"
#include "util/tracing_threads.h"

namespace tcfarm {
namespace {

constexpr int kMeshes = 8;
constexpr int kRings = 80, kSegments = 80;  // 2 * 80 * 80 = 12,800 triangles a mesh

// The geometry of a UV sphere of `radius` at `center`, smooth (vertex normals): the
// members "vertices", "normals" and "triangles" of a scene mesh, 2 * rings * segments triangles.
std::string SphereGeometry(double cx, double cy, double cz, double radius, int rings = kRings,
                           int segments = kSegments) {
  std::string vertices, normals, triangles;
  for (int ring = 0; ring <= rings; ++ring) {
    const double theta = M_PI * ring / rings;
    for (int segment = 0; segment <= segments; ++segment) {
      const double phi = 2 * M_PI * segment / segments;
      const double nx = std::sin(theta) * std::cos(phi), ny = std::cos(theta), nz = std::sin(theta) * std::sin(phi);
      vertices += (vertices.empty() ? "" : ",") + std::string("[") + std::to_string(cx + radius * nx) + "," +
                  std::to_string(cy + radius * ny) + "," + std::to_string(cz + radius * nz) + "]";
      normals += (normals.empty() ? "" : ",") + std::string("[") + std::to_string(nx) + "," + std::to_string(ny) + "," +
                 std::to_string(nz) + "]";
    }
  }
  auto at = [&](int ring, int segment) { return ring * (segments + 1) + segment; };
  for (int ring = 0; ring < rings; ++ring) {
    for (int segment = 0; segment < segments; ++segment) {
      const int a = at(ring, segment), b = at(ring + 1, segment), c = at(ring + 1, segment + 1), d = at(ring, segment + 1);
      triangles += (triangles.empty() ? "" : ",") + std::string("[") + std::to_string(a) + "," + std::to_string(b) + "," +
                   std::to_string(c) + "],[" + std::to_string(a) + "," + std::to_string(c) + "," + std::to_string(d) + "]";
    }
  }
  return R"("vertices": [)" + vertices + R"(], "normals": [)" + normals + R"(], "triangles": [)" + triangles + "]";
}

std::string SphereMesh(double cx, double cy, double cz, double radius, int index) {
  const std::string spin = std::to_string(3 + index);
  return R"({"type": "mesh", "material": "clay", )" + SphereGeometry(cx, cy, cz, radius) +
         R"(, "motion": {"translation": {"polynomial": [[0, 0.02], [0], [0]]},
         "rotation": {"axis": [0.2, 1, 0.1], "degrees_per_frame": )" + spin + R"(}, "pivot": [)" + std::to_string(cx) +
         "," + std::to_string(cy) + "," + std::to_string(cz) + "]}}";
}

Scene MovingMeshes() {
  std::string shapes = R"({"type": "quad", "corner": [-20, 0, -20], "edge_u": [0, 0, 40], "edge_v": [40, 0, 0], "material": "clay"})";
  for (int i = 0; i < kMeshes; ++i) {
    shapes += "," + SphereMesh(-3.5 + i % 4 * 2.3, 0.9, -1 - i / 4 * 2.5, 0.85, i);
  }
  Scene scene = ParseScene(R"({"camera": {"position": [0, 3, 7], "look_at": [0, 0.8, -1.5]},
    "lights": [{"type": "point", "position": [3, 8, 4], "intensity": [80, 80, 80]}],
    "materials": {"clay": {"diffuse": [0.7, 0.6, 0.5]}},
    "shapes": [)" + shapes + R"(], "render": {"width": 640, "height": 480, "frames": {"start": 0, "count": 48}}})");
  PrepareForTracing(scene);
  return scene;
}

const Scene& SharedScene() {
  static const Scene scene = MovingMeshes();
  return scene;
}

void TraceMovingMeshes(benchmark::State& state) {
  const Scene& scene = SharedScene();
  EmbreeDevice device;
  TracingThreads threads;
  Tracer tracer(device, scene, threads);
  std::vector<float> rgb(static_cast<size_t>(scene.render.width) * scene.render.height * 3);
  int frame = 0;
  for (auto _ : state) {
    tracer.TraceFrame(frame, rgb.data());
    benchmark::DoNotOptimize(rgb.data());
    frame = (frame + 1) % scene.render.frameCount;
  }
  size_t triangles = 0;
  for (const Shape& shape : scene.shapes) triangles += shape.Mesh().triangles.size();
  state.counters["triangles"] = static_cast<double>(triangles);
  state.counters["frames/s"] = benchmark::Counter(state.iterations(), benchmark::Counter::kIsRate);
}

// The same frames with nothing but Embree: each mesh in its own scene, instanced per frame
// at its motion's matrix into a top level over the still floor, as the tracer places them.
class BareEmbreeFrames {
 public:
  BareEmbreeFrames(RTCDevice device, const Scene& scene) : device_(device), scene_(scene) {
    for (const Shape& shape : scene.shapes) {
      RTCScene own = rtcNewScene(device);
      RTCGeometry geometry = rtcNewGeometry(device, shape.type == Shape::Type::kQuad ? RTC_GEOMETRY_TYPE_QUAD
                                                                                    : RTC_GEOMETRY_TYPE_TRIANGLE);
      std::vector<Vec3> points = shape.Mesh().vertices;
      std::vector<unsigned> indices;
      if (shape.type == Shape::Type::kQuad) {
        const Vec3 &c = shape.corner, &u = shape.edgeU, &v = shape.edgeV;
        points = {c, {c.x + u.x, c.y + u.y, c.z + u.z}, {c.x + u.x + v.x, c.y + u.y + v.y, c.z + u.z + v.z},
                  {c.x + v.x, c.y + v.y, c.z + v.z}};
        indices = {0, 1, 2, 3};
      } else {
        for (const auto& t : shape.Mesh().triangles) indices.insert(indices.end(), t.begin(), t.end());
      }
      auto* vertex = static_cast<float*>(rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                                 3 * sizeof(float), points.size()));
      for (size_t i = 0; i < points.size(); ++i) {
        for (int axis = 0; axis < 3; ++axis) vertex[3 * i + axis] = static_cast<float>(points[i][axis]);
      }
      const bool quad = shape.type == Shape::Type::kQuad;
      auto* index = static_cast<unsigned*>(rtcSetNewGeometryBuffer(
          geometry, RTC_BUFFER_TYPE_INDEX, 0, quad ? RTC_FORMAT_UINT4 : RTC_FORMAT_UINT3,
          (quad ? 4 : 3) * sizeof(unsigned), indices.size() / (quad ? 4 : 3)));
      std::copy(indices.begin(), indices.end(), index);
      rtcCommitGeometry(geometry);
      rtcAttachGeometry(own, geometry);
      rtcReleaseGeometry(geometry);
      rtcCommitScene(own);
      scenes_.push_back(own);
    }
  }
  ~BareEmbreeFrames() {
    for (RTCScene scene : scenes_) rtcReleaseScene(scene);
  }

  RTCScene Place(int frame) const {
    RTCScene top = rtcNewScene(device_);
    rtcSetSceneBuildQuality(top, RTC_BUILD_QUALITY_LOW);
    for (size_t i = 0; i < scenes_.size(); ++i) {
      const Affine placed = scene_.shapes[i].motion.WorldFromObject(frame);
      float matrix[12];
      for (int column = 0; column < 3; ++column) {
        for (int row = 0; row < 3; ++row) matrix[3 * column + row] = static_cast<float>(placed.linear[row][column]);
      }
      for (int row = 0; row < 3; ++row) matrix[9 + row] = static_cast<float>(placed.offset[row]);
      RTCGeometry instance = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_INSTANCE);
      rtcSetGeometryInstancedScene(instance, scenes_[i]);
      rtcSetGeometryTransform(instance, 0, RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR, matrix);
      rtcCommitGeometry(instance);
      rtcAttachGeometry(top, instance);
      rtcReleaseGeometry(instance);
    }
    rtcCommitScene(top);
    return top;
  }

 private:
  RTCDevice device_;
  const Scene& scene_;
  std::vector<RTCScene> scenes_;
};

void BareEmbreeLoop(benchmark::State& state) {
  const Scene& scene = SharedScene();
  EmbreeDevice device;
  TracingThreads threads;
  BareEmbreeFrames frames(device.get(), scene);
  const int width = scene.render.width, height = scene.render.height;
  const CameraPose pose = scene.camera.At(0);
  const Vec3 light = scene.lights[0].PositionAt(0);
  // The tracer's camera, built the same way (position - look_at in double).
  const Vec3 forward = NormalizeD(SubtractD(pose.lookAt, pose.position));
  const Vec3 right = NormalizeD(CrossD(forward, pose.up)), up = CrossD(right, forward);
  const double tanHalf = std::tan(scene.camera.verticalFovDegrees * M_PI / 360.0), aspect = double(width) / height;
  std::vector<float> rgb(static_cast<size_t>(width) * height * 3);
  int frame = 0;
  for (auto _ : state) {
    RTCScene top = frames.Place(frame);
    threads.ParallelFor(static_cast<size_t>(width) * height, 128, [&](size_t begin, size_t end) {
      RTCIntersectContext context;
      rtcInitIntersectContext(&context);
      for (size_t first = begin; first < end; first += 8) {
        alignas(32) int valid[8] = {};
        alignas(32) RTCRayHit8 packet{};
        const int lanes = static_cast<int>(std::min<size_t>(8, end - first));
        for (int lane = 0; lane < lanes; ++lane) {
          const size_t pixel = first + lane;
          const double sx = 2.0 * (pixel % width + 0.5) / width - 1, sy = 1 - 2.0 * (pixel / width + 0.5) / height;
          Vec3 d{forward.x + (right.x * sx * aspect + up.x * sy) * tanHalf,
                 forward.y + (right.y * sx * aspect + up.y * sy) * tanHalf,
                 forward.z + (right.z * sx * aspect + up.z * sy) * tanHalf};
          d = NormalizeD(d);
          valid[lane] = -1;
          packet.ray.org_x[lane] = float(pose.position.x), packet.ray.org_y[lane] = float(pose.position.y);
          packet.ray.org_z[lane] = float(pose.position.z);
          packet.ray.dir_x[lane] = float(d.x), packet.ray.dir_y[lane] = float(d.y), packet.ray.dir_z[lane] = float(d.z);
          packet.ray.tfar[lane] = INFINITY;
          packet.ray.mask[lane] = ~0u;
          packet.hit.geomID[lane] = RTC_INVALID_GEOMETRY_ID;
        }
        rtcIntersect8(valid, top, &context, &packet);
        alignas(32) int shadowValid[8] = {};
        alignas(32) RTCRay8 shadow{};
        float cosine[8] = {};
        for (int lane = 0; lane < lanes; ++lane) {
          if (packet.hit.geomID[lane] == RTC_INVALID_GEOMETRY_ID) continue;
          const float t = packet.ray.tfar[lane];
          const float px = packet.ray.org_x[lane] + t * packet.ray.dir_x[lane];
          const float py = packet.ray.org_y[lane] + t * packet.ray.dir_y[lane];
          const float pz = packet.ray.org_z[lane] + t * packet.ray.dir_z[lane];
          float lx = float(light.x) - px, ly = float(light.y) - py, lz = float(light.z) - pz;
          const float distance = std::sqrt(lx * lx + ly * ly + lz * lz);
          lx /= distance, ly /= distance, lz /= distance;
          float nx = packet.hit.Ng_x[lane], ny = packet.hit.Ng_y[lane], nz = packet.hit.Ng_z[lane];
          const float n = std::sqrt(nx * nx + ny * ny + nz * nz);
          cosine[lane] = std::fabs(nx * lx + ny * ly + nz * lz) / n;
          shadowValid[lane] = -1;
          shadow.org_x[lane] = px + 1e-4f * nx / n, shadow.org_y[lane] = py + 1e-4f * ny / n;
          shadow.org_z[lane] = pz + 1e-4f * nz / n;
          shadow.dir_x[lane] = lx, shadow.dir_y[lane] = ly, shadow.dir_z[lane] = lz;
          shadow.tfar[lane] = distance;
          shadow.mask[lane] = ~0u;
        }
        rtcOccluded8(shadowValid, top, &context, &shadow);
        for (int lane = 0; lane < lanes; ++lane) {
          const bool lit = shadowValid[lane] && shadow.tfar[lane] >= 0;
          rgb[3 * (first + lane)] = lit ? 0.7f * cosine[lane] : 0.0f;
        }
      }
    });
    rtcReleaseScene(top);
    benchmark::DoNotOptimize(rgb.data());
    frame = (frame + 1) % scene.render.frameCount;
  }
  state.counters["frames/s"] = benchmark::Counter(state.iterations(), benchmark::Counter::kIsRate);
}

// --- shared meshes -------------------------------------------------------------------
// N placements of one 10,082-triangle mesh (a UV sphere of 71 x 71), written inline in
// every shape or once in the scene's "meshes": the scene JSON a worker receives, and what
// it takes to parse, prepare and build the tracer's geometry (time, and heap bytes still
// held once built). Moving placements turn; still ones stand on a grid.
//   build/worker/mesh_bench --benchmark_filter=Placements

constexpr int kPlacementRings = 71, kPlacementSegments = 71;

std::string PlacementsScene(int placements, bool shared, bool moving) {
  const std::string geometry = SphereGeometry(0, 0, 0, 0.4, kPlacementRings, kPlacementSegments);
  std::string shapes;
  for (int i = 0; i < placements; ++i) {
    const std::string at = "[" + std::to_string(i % 25 - 12) + ", 0.5, " + std::to_string(-i / 25) + "]";
    const std::string motion = moving ? R"({"translation": )" + at +
                                            R"(, "rotation": {"axis": [0, 1, 0], "degrees_per_frame": 5}})"
                                      : at;
    shapes += std::string(i ? "," : "") + R"({"type": "mesh", )" +
              (shared ? R"("mesh_ref": "ball")" : geometry) + R"(, "motion": )" + motion + "}";
  }
  const std::string meshes = shared ? R"("meshes": {"ball": {)" + geometry + "}}," : "";
  return R"({"camera": {"position": [0, 6, 12], "look_at": [0, 0, -5]}, )" + meshes + R"( "shapes": [)" + shapes +
         R"(], "render": {"width": 64, "height": 48, "frames": {"start": 0, "count": 8}}})";
}

size_t HeapBytesInUse() {
  const struct mallinfo2 info = mallinfo2();
  return info.uordblks + info.hblkhd;
}

// Arguments: placements, shared (0 inline, 1 shared), moving (0 still, 1 moving).
void BuildPlacements(benchmark::State& state) {
  const int placements = static_cast<int>(state.range(0));
  const bool shared = state.range(1) != 0, moving = state.range(2) != 0;
  const std::string text = PlacementsScene(placements, shared, moving);
  EmbreeDevice device;
  TracingThreads threads;
  double heldBytes = 0;
  for (auto _ : state) {
    const size_t before = HeapBytesInUse();
    Scene scene = ParseScene(text);
    PrepareForTracing(scene);
    Tracer tracer(device, scene, threads);
    heldBytes = static_cast<double>(HeapBytesInUse() - before);
    benchmark::DoNotOptimize(&tracer);
  }
  state.counters["scene_json_MB"] = static_cast<double>(text.size()) / 1e6;
  state.counters["held_MB"] = heldBytes / 1e6;
}

BENCHMARK(BuildPlacements)
    ->ArgsProduct({{10, 100}, {0, 1}, {0, 1}})
    ->Args({500, 1, 1})  // a forest only sharing can afford (inline: ~240 MB of JSON)
    ->ArgNames({"placements", "shared", "moving"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

BENCHMARK(TraceMovingMeshes)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->UseRealTime();
BENCHMARK(BareEmbreeLoop)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->UseRealTime();

}  // namespace
}  // namespace tcfarm

BENCHMARK_MAIN();
