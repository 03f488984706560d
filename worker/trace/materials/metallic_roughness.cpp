#include "worker/trace/materials/metallic_roughness.h"

#include <algorithm>
#include <cmath>

#include "worker/trace/barycentric.h"
#include "worker/trace/materials/gltf_surface_rule.h"
#include "worker/trace/pixel_tracer.h"

namespace tcfarm {
namespace {

using PixelTracer = Tracer::PixelTracer;
using ShapeShading = PixelTracer::ShapeShading;
using RawHit = PixelTracer::RawHit;
using SurfaceHit = PixelTracer::SurfaceHit;

// The triangle's texel density is its texture coordinates' area over its area in the
// world: its scene vertices (a deforming mesh's rest pose) as this frame places them.
UvFootprint TextureFootprint(const PixelTracer& tracer, const ShapeShading& shape, const RawHit& raw,
                             const SurfaceHit& hit) {
  UvFootprint footprint;
  if (!(hit.coneWidth > 0)) return footprint;
  const auto& corner = shape.triangles[raw.primitiveId];
  const std::vector<Vec3>& vertices = tracer.scene().shapes[static_cast<size_t>(hit.shape)].Mesh().vertices;
  const Vec3 &p0 = vertices[corner[0]], &p1 = vertices[corner[1]], &p2 = vertices[corner[2]];
  const Vec3 cross = tracer.geometry().AreaToWorld(hit.shape, CrossD(SubtractD(p1, p0), SubtractD(p2, p0)));
  const double worldArea = std::sqrt(DotD(cross, cross));
  const float cosine = Dot(hit.direction, hit.faceNormal);
  if (shape.uvs) footprint.log2Width[0] = Log2UvWidth(hit.coneWidth, cosine, UvArea2(shape.uvs, corner), worldArea);
  if (shape.uvs1) footprint.log2Width[1] = Log2UvWidth(hit.coneWidth, cosine, UvArea2(shape.uvs1, corner), worldArea);
  return footprint;
}

// The hit triangle's direction of increasing u over the normal map's texture coordinates
// `uvs`, in object space, and the sign of its bitangent (v's direction against normal x
// tangent).
Float3 TriangleTangent(const PixelTracer& tracer, const std::array<float, 2>* uvs, const ShapeShading& shape,
                       const RawHit& raw, int shapeIndex, float* handedness) {
  const auto& corner = shape.triangles[raw.primitiveId];
  const std::vector<Vec3>& vertices = tracer.scene().shapes[static_cast<size_t>(shapeIndex)].Mesh().vertices;
  const Vec3 &p0 = vertices[corner[0]], &p1 = vertices[corner[1]], &p2 = vertices[corner[2]];
  const Vec3 e1 = SubtractD(p1, p0), e2 = SubtractD(p2, p0);
  const double du1 = uvs[corner[1]][0] - uvs[corner[0]][0], dv1 = uvs[corner[1]][1] - uvs[corner[0]][1];
  const double du2 = uvs[corner[2]][0] - uvs[corner[0]][0], dv2 = uvs[corner[2]][1] - uvs[corner[0]][1];
  const double det = du1 * dv2 - du2 * dv1;
  if (det == 0) return {};
  // dp/du and dp/dv, solved from the two edges.
  const Vec3 dpdu{(dv2 * e1.x - dv1 * e2.x) / det, (dv2 * e1.y - dv1 * e2.y) / det, (dv2 * e1.z - dv1 * e2.z) / det};
  const Vec3 dpdv{(du1 * e2.x - du2 * e1.x) / det, (du1 * e2.y - du2 * e1.y) / det, (du1 * e2.z - du2 * e1.z) / det};
  // glTF's v runs down the image while a normal map's green points up it: unmirrored
  // texture coordinates have n x t along -dp/dv (w = +1, as TANGENT has it); mirrored
  // ones flip the bitangent (w = -1), as MikkTSpace's sign says.
  const Vec3 normal = CrossD(e1, e2);
  *handedness = DotD(CrossD(normal, dpdu), dpdv) < 0 ? 1.0f : -1.0f;
  return ToFloat3(dpdu);
}

// A normal map's normal: the texel (tangent space, [0, 1] codes for [-1, 1], x and y
// scaled) in the frame of the hit's tangent, bitangent and shading normal. The tangent is
// the mesh's (TANGENT) where it has them, else the triangle's direction of increasing u
// over the material's normal map's coordinates; either is made perpendicular to the
// shading normal. Zero when the frame is degenerate.
Float3 TangentFrameNormal(const PixelTracer& tracer, const PbrMaterial& material, const ShapeShading& shape,
                          const RawHit& raw, const SurfaceHit& hit, const PbrTexture& map, Float3 texel) {
  const auto& corner = shape.triangles[raw.primitiveId];
  Float3 tangent;
  float handedness = 1;
  if (shape.tangents) {
    const float w = 1.0f - raw.u - raw.v;
    const auto &a = shape.tangents[corner[0]], &b = shape.tangents[corner[1]], &c = shape.tangents[corner[2]];
    tangent = Float3{a[0], a[1], a[2]} * w + Float3{b[0], b[1], b[2]} * raw.u + Float3{c[0], c[1], c[2]} * raw.v;
    handedness = a[3] < 0 ? -1.0f : 1.0f;
  } else {
    const std::array<float, 2>* uvs = material.normalTexture.texCoord == 0 ? shape.uvs : shape.uvs1;
    tangent = TriangleTangent(tracer, uvs, shape, raw, hit.shape, &handedness);
  }
  tangent = tracer.ToWorld(hit.shape, tracer.geometry().HasNormalTransform(hit.shape), tangent);
  const Float3 n = hit.normal;
  tangent = tangent - n * Dot(n, tangent);
  const float length = Length(tangent);
  if (!(length > 1e-12f)) return {};
  tangent = tangent * (1.0f / length);
  // The bitangent follows the shading normal's side, so a surface seen from behind keeps
  // its bumps.
  const Float3 bitangent = Cross(n, tangent) * handedness;
  const float x = (texel.x * 2.0f - 1.0f) * map.amount, y = (texel.y * 2.0f - 1.0f) * map.amount;
  const float z = texel.z * 2.0f - 1.0f;
  const Float3 mapped = tangent * x + bitangent * y + n * z;
  const float mappedLength = Length(mapped);
  return mappedLength > 0 && std::isfinite(mappedLength) ? mapped * (1.0f / mappedLength) : Float3{};
}

// The hit's normal as normal map `map` tilts it; the hit's normal itself where the map is
// missing, lacks its texture coordinates, or gives no normal.
Float3 MappedNormal(const PixelTracer& tracer, const PbrMaterial& material, const ShapeShading& shape,
                    const RawHit& raw, const SurfaceHit& hit, const PbrTexture& map, std::array<float, 2> uv0,
                    std::array<float, 2> uv1, const UvFootprint& footprint) {
  // A normal map needs the texture coordinates it was painted over.
  const bool mapped = map && shape.triangles && (map.texCoord == 0 ? shape.uvs : shape.uvs1);
  if (!mapped) return hit.normal;
  const Float3 n = TangentFrameNormal(tracer, material, shape, raw, hit, map,
                                      map.Sample(map.texCoord == 0 ? uv0 : uv1, footprint));
  return IsZero(n) ? hit.normal : n;
}

}  // namespace

MetallicRoughnessShading::MetallicRoughnessShading(const MetallicRoughness& m, const TextureLoader& load, bool used)
    : gltf(m, used ? load : TextureLoader([](const Texture&, TextureImage::Encoding) { return nullptr; })) {}

std::unique_ptr<SurfaceRule> MetallicRoughnessShading::SurfaceRuleFor(const Shape& shape, const MetallicRoughness& m,
                                                                      const ShapeUvSets& uvs, const TextureLoader& load) {
  return GltfSurfaceRule::For(shape, m, uvs, load);
}

// Defined for the tracer alone (instantiated below): the tracer's types stay out of the
// header, and the calls stay calls.
template <typename Tracer>
void MetallicRoughnessShading::Shade(const Tracer& tracer, const typename Tracer::ShapeShading& shape,
                                     const typename Tracer::RawHit& raw, typename Tracer::SurfaceHit& hit) const {
  std::array<float, 2> uv0{0, 0}, uv1{0, 0};
  Float3 vertexColor{1, 1, 1};
  UvFootprint footprint;
  if (shape.triangles) {
    if (gltf.Textured()) footprint = TextureFootprint(tracer, shape, raw, hit);
    const auto& corner = shape.triangles[raw.primitiveId];
    if (shape.uvs) uv0 = AtBarycentric(shape.uvs, corner, raw.u, raw.v);
    if (shape.uvs1) uv1 = AtBarycentric(shape.uvs1, corner, raw.u, raw.v);
    if (shape.colors) vertexColor = AtBarycentric(shape.colors, corner, raw.u, raw.v);
  }
  PbrSurface s = gltf.Surface(uv0, uv1, vertexColor, footprint);
  // The coat's normal: its own map over the surface's normal, not over the normal map's.
  if (s.clearcoat > 0) {
    s.clearcoatNormal = MappedNormal(tracer, gltf, shape, raw, hit, gltf.clearcoatNormalTexture, uv0, uv1, footprint);
  }
  hit.normal = MappedNormal(tracer, gltf, shape, raw, hit, gltf.normalTexture, uv0, uv1, footprint);
  hit.surface = s;
}

Float3 MetallicRoughnessShading::Ambient(const PbrSurface& s, Float3 arriving, float ambient) const {
  if (gltf.unlit) return s.baseColor;
  // A uniform sky of radiance `ambient` reflects about the diffuse colour and f0 of it.
  const Float3 reflected = s.baseColor * (1.0f - s.metallic) + SurfaceF0(s, gltf.constants);
  if (s.clearcoat > 0) {
    // A coat reflects its share of the sky whole, and dims what lies beneath it, emission too.
    const float coat = ClearcoatWeight(s, -arriving);
    return (reflected * (1.0f - coat) + Float3{coat, coat, coat}) * (ambient * s.occlusion) + s.emission * (1.0f - coat);
  }
  return reflected * (ambient * s.occlusion) + s.emission;
}

Float3 MetallicRoughnessShading::Reflected(const PbrSurface& s, Float3 towardLight, Float3 normal, Float3 arriving) const {
  return PbrReflected(s, gltf.constants, towardLight, normal, -arriving);
}

// A smooth surface mirrors what it faces, weighted by Fresnel at the viewing angle; a
// transmitting one refracts its share (KHR_materials_transmission), the rest of its light
// as it was. A coat takes its weight of both, and a smooth coat mirrors about its own
// normal. (Under transmission the coat's highlights of lights, in `local`, are weighed as
// the rest of it: a coated glass is rare.)
template <typename Tracer>
Float3 MetallicRoughnessShading::Combine(Tracer& tracer, const typename Tracer::SurfaceHit& hit, const PbrSurface& s,
                                         Float3 local, int depth) const {
  Float3 color = local;
  const Float3 mirror = Reflect(hit.direction, hit.normal);
  const float coat = s.clearcoat > 0 ? ClearcoatWeight(s, -hit.direction) : 0.0f;
  if (s.roughness < PbrMaterial::kMirrorRoughness) {
    const float nDotV = std::max(-Dot(hit.direction, hit.normal), 0.0f);
    const Float3 fresnel = Schlick(SurfaceF0(s, gltf.constants), SurfaceF90(s, gltf.constants), nDotV);
    color += tracer.Secondary(hit, false, mirror, depth) * (coat > 0 ? fresnel * (1.0f - coat) : fresnel);
  }
  const float transmitted = gltf.transmission * (1.0f - s.metallic);
  if (transmitted > 0) {
    const float eta = hit.fromInside ? gltf.indexOfRefraction : 1.0f / gltf.indexOfRefraction;
    Float3 refracted;
    Float3 through;
    if (!Refract(hit.direction, hit.normal, eta, &refracted)) {  // total internal reflection
      through = tracer.Secondary(hit, false, mirror, depth);
    } else {
      through = tracer.Secondary(hit, true, refracted, depth);
    }
    color = color * (1.0f - transmitted) + through * (coat > 0 ? transmitted * (1.0f - coat) : transmitted);
  }
  if (coat > 0 && s.clearcoatRoughness < PbrMaterial::kMirrorRoughness) {
    color += tracer.Secondary(hit, false, Reflect(hit.direction, s.clearcoatNormal), depth) * coat;
  }
  // A blended surface covers alpha of the ray; the rest goes straight on past it.
  if (gltf.blends && s.alpha < 1) {
    const Float3 behind = tracer.Secondary(hit, true, hit.direction, depth);
    color = color * s.alpha + behind * (1.0f - s.alpha);
  }
  return color;
}

template void MetallicRoughnessShading::Shade(const PixelTracer&, const ShapeShading&, const RawHit&, SurfaceHit&) const;
template Float3 MetallicRoughnessShading::Combine(PixelTracer&, const SurfaceHit&, const PbrSurface&, Float3, int) const;

}  // namespace tcfarm
