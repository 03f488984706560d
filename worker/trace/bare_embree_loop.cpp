#include "worker/trace/bare_embree_loop.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>

#include "worker/embree/ray_packets.h"
#include "worker/embree/scene_geometry.h"
#include "worker/shapes/shape_kind.h"
#include "worker/trace/camera.h"
#include "worker/trace/float3.h"
#include "worker/trace/lights.h"
#include "worker/trace/materials.h"
#include "worker/trace/materials/gltf_brdf.h"
#include "worker/trace/ray_offset.h"

namespace tcfarm {
namespace {

constexpr float kInfinity = std::numeric_limits<float>::infinity();

void ApplyFlags(RTCScene scene, BareEmbreeLoop::Flags flags, bool robust) {
  if (flags != BareEmbreeLoop::Flags::kTracers) return;
  if (robust) rtcSetSceneFlags(scene, RTC_SCENE_FLAG_ROBUST);
  rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_HIGH);
}

void AttachInstance(RTCDevice device, RTCScene top, RTCScene child, const Affine& placement) {
  float matrix[12];  // column-major 3x4
  for (int column = 0; column < 3; ++column) {
    for (int row = 0; row < 3; ++row) matrix[3 * column + row] = static_cast<float>(placement.linear[row][column]);
  }
  for (int row = 0; row < 3; ++row) matrix[9 + row] = static_cast<float>(placement.offset[row]);
  RTCGeometry instance = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_INSTANCE);
  rtcSetGeometryInstancedScene(instance, child);
  rtcSetGeometryTransform(instance, 0, RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR, matrix);
  rtcCommitGeometry(instance);
  rtcAttachGeometry(top, instance);
  rtcReleaseGeometry(instance);
}

// Normals go to the world by the inverse transpose of the linear part, up to a scale the
// shading normalises away: the cofactor matrix.
std::array<float, 9> NormalMatrix(const Affine& placement) {
  double cofactor[3][3];
  Cofactor(placement.linear, cofactor);
  std::array<float, 9> out;
  for (int row = 0; row < 3; ++row) {
    for (int column = 0; column < 3; ++column) out[3 * row + column] = static_cast<float>(cofactor[row][column]);
  }
  return out;
}

// A primary hit as the shading needs it.
struct LaneHit {
  Float3 position, normal, arriving;
  float offset;
  // Its material: Phong's, or else glTF's (Covers: no other model).
  const PhongShading* phong;
  const MetallicRoughnessShading* gltf;
  PbrSurface pbr;  // a glTF material's inputs at the hit
};

// What a glTF surface shows with no light: the sky's ambient share of its diffuse colour
// and f0, and its emission (its own colour when unlit), as the tracer has it.
Float3 PbrAmbient(const PbrMaterial& m, const PbrSurface& s) {
  if (m.unlit) return s.baseColor;
  return (s.baseColor * (1.0f - s.metallic) + SurfaceF0(s, m.constants)) * (kAmbient * s.occlusion) + s.emission;
}

// Light of unit intensity from `towardLight` reflected toward the camera.
Float3 Reflected(const LaneHit& hit, Float3 towardLight) {
  if (hit.gltf) return PbrReflected(hit.pbr, hit.gltf->gltf.constants, towardLight, hit.normal, -hit.arriving);
  return hit.phong->Reflected({hit.phong->diffuse}, towardLight, hit.normal, hit.arriving);
}

}  // namespace

BareEmbreeLoop::BareEmbreeLoop(RTCDevice device, const Scene& scene, Flags flags)
    : device_(device),
      scene_(scene),
      flags_(flags),
      packetWidth_(NativePacketWidth(device)),
      robust_(flags == Flags::kTracers && NeedsRobustTraversal(scene)) {
  for (size_t i = 0; i < scene.shapes.size(); ++i) {
    const Shape& shape = scene.shapes[i];
    RTCScene target;
    if (shape.motion.IsNone()) {
      if (!still_) still_ = NewShapesScene(robust_);
      target = still_;
    } else {
      movers_.emplace_back(static_cast<int>(i), NewShapesScene(robust_ && HasSharedEdges(shape)));
      target = movers_.back().second;
    }
    RTCGeometry geometry = KindOf(shape).NewGeometry(device, shape);
    rtcCommitGeometry(geometry);
    const unsigned id = rtcAttachGeometry(target, geometry);
    rtcReleaseGeometry(geometry);
    if (target == still_) {
      stillShapeOfGeometry_.resize(std::max<size_t>(stillShapeOfGeometry_.size(), id + 1), -1);
      stillShapeOfGeometry_[id] = static_cast<int>(i);
    }
  }
  if (still_) rtcCommitScene(still_);
  for (auto& mover : movers_) rtcCommitScene(mover.second);
  // Textures are decoded once, before any frame: glTF materials read theirs; Phong's
  // textures are the tracer's own work.
  materials_ = MakeMaterials(scene, [this](const Texture& texture, TextureImage::Encoding encoding) {
    return textures_.emplace_back(std::make_unique<TextureImage>(texture, encoding)).get();
  });
  MakePbrMeshes();
}

void BareEmbreeLoop::MakePbrMeshes() {
  std::map<const TriangleMesh*, std::shared_ptr<const PbrMesh>> byMesh;
  for (const Shape& shape : scene_.shapes) {
    auto& entry = pbrMeshes_.emplace_back();
    const ShadingMaterial& material = materials_[static_cast<size_t>(shape.material)];
    if (!std::holds_alternative<MetallicRoughnessShading>(material) || shape.Mesh().triangles.empty()) continue;
    auto& shared = byMesh[&shape.Mesh()];
    if (!shared) {
      const TriangleMesh& mesh = shape.Mesh();
      auto made = std::make_shared<PbrMesh>();
      made->triangles = &mesh.triangles;
      for (const auto& uv : mesh.uvs) made->uvs.push_back({static_cast<float>(uv[0]), static_cast<float>(uv[1])});
      for (const auto& uv : mesh.uvs1) made->uvs1.push_back({static_cast<float>(uv[0]), static_cast<float>(uv[1])});
      for (const Vec3& color : mesh.colors) made->colors.push_back(ToFloat3(color));
      shared = std::move(made);
    }
    entry = shared;
  }
}

PbrSurface BareEmbreeLoop::SurfaceAt(int shape, unsigned primitive, float u, float v) const {
  const PbrMaterial& material =
      std::get<MetallicRoughnessShading>(materials_[static_cast<size_t>(scene_.shapes[shape].material)]).gltf;
  std::array<float, 2> uv0{0, 0}, uv1{0, 0};
  Float3 color{1, 1, 1};
  if (const PbrMesh* mesh = pbrMeshes_[shape].get()) {
    const auto& corner = (*mesh->triangles)[primitive];
    const float w = 1.0f - u - v;
    auto interpolate = [&](const std::vector<std::array<float, 2>>& uvs) -> std::array<float, 2> {
      const auto &a = uvs[corner[0]], &b = uvs[corner[1]], &c = uvs[corner[2]];
      return {a[0] * w + b[0] * u + c[0] * v, a[1] * w + b[1] * u + c[1] * v};
    };
    if (!mesh->uvs.empty()) uv0 = interpolate(mesh->uvs);
    if (!mesh->uvs1.empty()) uv1 = interpolate(mesh->uvs1);
    if (!mesh->colors.empty()) {
      color = mesh->colors[corner[0]] * w + mesh->colors[corner[1]] * u + mesh->colors[corner[2]] * v;
    }
  }
  return material.Surface(uv0, uv1, color);
}

BareEmbreeLoop::~BareEmbreeLoop() {
  for (auto& [frame, placed] : placed_) {
    if (placed.scene != still_) rtcReleaseScene(placed.scene);
  }
  for (auto& mover : movers_) rtcReleaseScene(mover.second);
  if (still_) rtcReleaseScene(still_);
}

bool BareEmbreeLoop::Covers(const Scene& scene) {
  const bool known = std::all_of(scene.materials.begin(), scene.materials.end(), [](const Material& m) {
    return m.Is<Phong>() || m.Is<MetallicRoughness>();
  });
  return known && (scene.render.maxDepth == 0 || (!scene.AnyMaterialReflects() && !scene.AnyMaterialRefracts()));
}

RTCScene BareEmbreeLoop::NewShapesScene(bool robust) const {
  RTCScene scene = rtcNewScene(device_);
  ApplyFlags(scene, flags_, robust);
  return scene;
}

const BareEmbreeLoop::Placed& BareEmbreeLoop::Place(int frame) {
  auto [it, isNew] = placed_.try_emplace(frame);
  Placed& placed = it->second;
  if (!isNew) return placed;
  if (movers_.empty()) {  // nothing moves: the still scene itself, no instance
    placed.scene = still_;
    return placed;
  }
  placed.scene = rtcNewScene(device_);
  rtcSetSceneBuildQuality(placed.scene, RTC_BUILD_QUALITY_LOW);
  if (robust_) rtcSetSceneFlags(placed.scene, RTC_SCENE_FLAG_ROBUST);
  if (still_) {
    AttachInstance(device_, placed.scene, still_, Affine{});
    placed.shapeOfInstance.push_back(-1);
    placed.normalToWorld.push_back({1, 0, 0, 0, 1, 0, 0, 0, 1});
  }
  for (const auto& [shape, own] : movers_) {
    const Affine worldFromObject = scene_.shapes[shape].motion.WorldFromObject(frame);
    AttachInstance(device_, placed.scene, own, worldFromObject);
    placed.shapeOfInstance.push_back(shape);
    placed.normalToWorld.push_back(NormalMatrix(worldFromObject));
  }
  rtcCommitScene(placed.scene);
  return placed;
}

void BareEmbreeLoop::TraceFrame(int frame, TracingThreads& threads, float* rgb) {
  const Placed& placed = Place(frame);
  const FrameParts parts{placed,
                         MakeCamera(scene_, frame),
                         MakeLights(scene_, frame),
                         ToFloat3(scene_.background),
                         static_cast<uint32_t>(scene_.render.width),
                         scene_.render.samplesPerPixel};
  const size_t pixels = size_t{parts.width} * scene_.render.height;
  const size_t chunk = std::max<size_t>(128, pixels / (threads.ThreadCount() * 16));
  threads.ParallelFor(pixels, chunk, [&](size_t begin, size_t end) {
    std::fill(rgb + 3 * begin, rgb + 3 * end, 0.0f);
    WithPacketWidth(packetWidth_, [&](auto width) { TracePixels<decltype(width)::value>(parts, begin, end, rgb); });
  });
}

template <int Width>
void BareEmbreeLoop::TracePixels(const FrameParts& parts, size_t begin, size_t end, float* rgb) const {
  using Packet = RayPacket<Width>;
  const Placed& placed = parts.placed;
  const auto width = parts.width;
  const int spp = parts.spp;
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  const size_t items = (end - begin) * spp;
  for (size_t first = 0; first < items; first += Width) {
    const int lanes = static_cast<int>(std::min<size_t>(Width, items - first));
    alignas(64) int valid[Width] = {};
    alignas(64) typename Packet::RayHit packet{};
    for (int lane = 0; lane < lanes; ++lane) {
      const size_t item = first + lane, pixel = begin + item / spp;
      float px, py;
      SamplePosition(pixel % width, pixel / width, static_cast<int>(item % spp), spp, &px, &py);
      Float3 o, d;
      parts.camera.Ray(px, py, &o, &d);
      valid[lane] = -1;
      packet.ray.org_x[lane] = o.x, packet.ray.org_y[lane] = o.y, packet.ray.org_z[lane] = o.z;
      packet.ray.dir_x[lane] = d.x, packet.ray.dir_y[lane] = d.y, packet.ray.dir_z[lane] = d.z;
      packet.ray.tfar[lane] = kInfinity;
      packet.ray.mask[lane] = ~0u;
      packet.hit.geomID[lane] = RTC_INVALID_GEOMETRY_ID;
      packet.hit.instID[0][lane] = RTC_INVALID_GEOMETRY_ID;
    }
    Packet::Intersect(valid, placed.scene, &context, &packet);

    LaneHit hits[Width];
    Float3 color[Width];
    bool hasHit[Width] = {};
    for (int lane = 0; lane < lanes; ++lane) {
      if (packet.hit.geomID[lane] == RTC_INVALID_GEOMETRY_ID) {
        color[lane] = parts.background;
        continue;
      }
      hasHit[lane] = true;
      const unsigned instance = packet.hit.instID[0][lane];
      int shape;
      Float3 n{packet.hit.Ng_x[lane], packet.hit.Ng_y[lane], packet.hit.Ng_z[lane]};
      if (instance == RTC_INVALID_GEOMETRY_ID || placed.shapeOfInstance[instance] < 0) {
        shape = stillShapeOfGeometry_[packet.hit.geomID[lane]];
      } else {
        shape = placed.shapeOfInstance[instance];
        const auto& m = placed.normalToWorld[instance];
        n = {m[0] * n.x + m[1] * n.y + m[2] * n.z, m[3] * n.x + m[4] * n.y + m[5] * n.z,
             m[6] * n.x + m[7] * n.y + m[8] * n.z};
      }
      const Float3 o{packet.ray.org_x[lane], packet.ray.org_y[lane], packet.ray.org_z[lane]};
      const Float3 d{packet.ray.dir_x[lane], packet.ray.dir_y[lane], packet.ray.dir_z[lane]};
      const float t = packet.ray.tfar[lane];
      n = Normalize(n);
      LaneHit& hit = hits[lane];
      const ShadingMaterial& material = materials_[scene_.shapes[shape].material];
      hit = {o + d * t, Dot(n, d) > 0 ? -n : n, d, kRelativeRayOffset * (MaxAbsComponent(o) + t),
             std::get_if<PhongShading>(&material), std::get_if<MetallicRoughnessShading>(&material), {}};
      if (hit.gltf) {
        hit.pbr = SurfaceAt(shape, packet.hit.primID[lane], packet.hit.u[lane], packet.hit.v[lane]);
        if (hit.pbr.clearcoat > 0) hit.pbr.clearcoatNormal = hit.normal;  // no coat normal maps
        color[lane] = PbrAmbient(hit.gltf->gltf, hit.pbr);
      } else {
        color[lane] = hit.phong->diffuse * kAmbient;
      }
    }
    for (const ShadingLight& light : parts.lights) {
      alignas(64) int shadowValid[Width] = {};
      alignas(64) typename Packet::Ray shadow{};
      Float3 toLight[Width];
      float distance[Width];
      for (int lane = 0; lane < lanes; ++lane) {
        if (!hasHit[lane]) continue;
        const LaneHit& hit = hits[lane];
        if (hit.gltf && hit.gltf->gltf.unlit) continue;
        if (!light.Toward(hit.position, hit.normal, &toLight[lane], &distance[lane])) continue;
        const Float3 start = hit.position + hit.normal * hit.offset;
        shadowValid[lane] = -1;
        shadow.org_x[lane] = start.x, shadow.org_y[lane] = start.y, shadow.org_z[lane] = start.z;
        shadow.dir_x[lane] = toLight[lane].x, shadow.dir_y[lane] = toLight[lane].y;
        shadow.dir_z[lane] = toLight[lane].z;
        shadow.tfar[lane] = distance[lane];
        shadow.mask[lane] = ~0u;
      }
      Packet::Occluded(shadowValid, placed.scene, &context, &shadow);
      for (int lane = 0; lane < lanes; ++lane) {
        if (!shadowValid[lane] || shadow.tfar[lane] < 0) continue;
        const LaneHit& hit = hits[lane];
        color[lane] += Reflected(hit, toLight[lane]) * light.intensity * light.Arriving(toLight[lane], distance[lane]);
      }
    }
    for (int lane = 0; lane < lanes; ++lane) {
      float* out = rgb + 3 * (begin + (first + lane) / spp);
      out[0] += color[lane].x / spp, out[1] += color[lane].y / spp, out[2] += color[lane].z / spp;
    }
  }
}

}  // namespace tcfarm
