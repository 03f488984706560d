// What glTF's metallic-roughness model asks of a hit: its textures' inputs (with their
// footprint), normal maps and their tangent frames, its ray tree (mirror, transmission,
// blending) and the light that passes blended surfaces (proto/scene.md, "glTF materials").
#include <algorithm>
#include <cmath>

#include "worker/trace/barycentric.h"
#include "worker/trace/pixel_tracer.h"

namespace tcfarm {

void Tracer::PixelTracer::ShadePbr(const ShapeShading& shape, const RawHit& raw, SurfaceHit& hit) const {
  std::array<float, 2> uv0{0, 0}, uv1{0, 0};
  Float3 vertexColor{1, 1, 1};
  const PbrMaterial& material = *shape.pbr;
  UvFootprint footprint;
  if (shape.triangles) {
    if (material.Textured()) footprint = TextureFootprint(shape, raw, hit);
    const auto& corner = shape.triangles[raw.primitiveId];
    if (shape.uvs) uv0 = AtBarycentric(shape.uvs, corner, raw.u, raw.v);
    if (shape.uvs1) uv1 = AtBarycentric(shape.uvs1, corner, raw.u, raw.v);
    if (shape.colors) vertexColor = AtBarycentric(shape.colors, corner, raw.u, raw.v);
  }
  hit.pbr = material.Surface(uv0, uv1, vertexColor, footprint);
  // The coat's normal: its own map over the surface's normal, not over the normal map's.
  if (hit.pbr.clearcoat > 0) {
    hit.pbr.clearcoatNormal = MappedNormal(shape, raw, hit, material.clearcoatNormalTexture, uv0, uv1, footprint);
  }
  hit.normal = MappedNormal(shape, raw, hit, material.normalTexture, uv0, uv1, footprint);
}

// The triangle's texel density is its texture coordinates' area over its area in the
// world: its scene vertices (a deforming mesh's rest pose) as this frame places them.
UvFootprint Tracer::PixelTracer::TextureFootprint(const ShapeShading& shape, const RawHit& raw,
                                                  const SurfaceHit& hit) const {
  UvFootprint footprint;
  if (!(hit.coneWidth > 0)) return footprint;
  const auto& corner = shape.triangles[raw.primitiveId];
  const std::vector<Vec3>& vertices = scene_.shapes[static_cast<size_t>(hit.shape)].Mesh().vertices;
  const Vec3 &p0 = vertices[corner[0]], &p1 = vertices[corner[1]], &p2 = vertices[corner[2]];
  const Vec3 cross = frame_.geometry->AreaToWorld(hit.shape, CrossD(SubtractD(p1, p0), SubtractD(p2, p0)));
  const double worldArea = std::sqrt(DotD(cross, cross));
  const float cosine = Dot(hit.direction, hit.faceNormal);
  if (shape.uvs) footprint.log2Width[0] = Log2UvWidth(hit.coneWidth, cosine, UvArea2(shape.uvs, corner), worldArea);
  if (shape.uvs1) footprint.log2Width[1] = Log2UvWidth(hit.coneWidth, cosine, UvArea2(shape.uvs1, corner), worldArea);
  return footprint;
}

Float3 Tracer::PixelTracer::MappedNormal(const ShapeShading& shape, const RawHit& raw, const SurfaceHit& hit,
                                         const PbrTexture& map, std::array<float, 2> uv0,
                                         std::array<float, 2> uv1, const UvFootprint& footprint) const {
  // A normal map needs the texture coordinates it was painted over.
  const bool mapped = map && shape.triangles && (map.texCoord == 0 ? shape.uvs : shape.uvs1);
  if (!mapped) return hit.normal;
  const Float3 n = TangentFrameNormal(shape, raw, hit, map, map.Sample(map.texCoord == 0 ? uv0 : uv1, footprint));
  return IsZero(n) ? hit.normal : n;
}

// A normal map's normal: the texel (tangent space, [0, 1] codes for [-1, 1], x and y
// scaled) in the frame of the hit's tangent, bitangent and shading normal. The tangent is
// the mesh's (TANGENT) where it has them, else the triangle's direction of increasing u;
// either is made perpendicular to the shading normal. Zero when the frame is degenerate.
Float3 Tracer::PixelTracer::TangentFrameNormal(const ShapeShading& shape, const RawHit& raw, const SurfaceHit& hit,
                                               const PbrTexture& map, Float3 texel) const {
  const auto& corner = shape.triangles[raw.primitiveId];
  Float3 tangent;
  float handedness = 1;
  if (shape.tangents) {
    const float w = 1.0f - raw.u - raw.v;
    const auto &a = shape.tangents[corner[0]], &b = shape.tangents[corner[1]], &c = shape.tangents[corner[2]];
    tangent = Float3{a[0], a[1], a[2]} * w + Float3{b[0], b[1], b[2]} * raw.u + Float3{c[0], c[1], c[2]} * raw.v;
    handedness = a[3] < 0 ? -1.0f : 1.0f;
  } else {
    tangent = TriangleTangent(shape, raw, hit.shape, &handedness);
  }
  tangent = ToWorld(hit.shape, frame_.geometry->HasNormalTransform(hit.shape), tangent);
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

// glTF materials: a smooth surface mirrors what it faces, weighted by Fresnel at the
// viewing angle; a transmitting one refracts its share (KHR_materials_transmission), the
// rest of its light as it was. A coat takes its weight of both, and a smooth coat mirrors
// about its own normal. (Under transmission the coat's highlights of lights, in `local`,
// are weighed as the rest of it: a coated glass is rare.)
Float3 Tracer::PixelTracer::CombinePbr(const SurfaceHit& hit, const PbrMaterial& material, Float3 local, int depth) {
  Float3 color = local;
  const Float3 mirror = Reflect(hit.direction, hit.normal);
  const float coat = hit.pbr.clearcoat > 0 ? ClearcoatWeight(hit.pbr, -hit.direction) : 0.0f;
  if (hit.pbr.roughness < PbrMaterial::kMirrorRoughness) {
    const float nDotV = std::max(-Dot(hit.direction, hit.normal), 0.0f);
    const Float3 fresnel = Schlick(SurfaceF0(hit.pbr, material.constants), SurfaceF90(hit.pbr, material.constants), nDotV);
    ++counts_.reflection;
    color += TraceRay(Spawn(hit, false), mirror, depth + 1, hit.coneWidth) * (coat > 0 ? fresnel * (1.0f - coat) : fresnel);
  }
  const float transmitted = material.transmission * (1.0f - hit.pbr.metallic);
  if (transmitted > 0) {
    const float eta = hit.fromInside ? material.indexOfRefraction : 1.0f / material.indexOfRefraction;
    Float3 refracted;
    Float3 through;
    if (!Refract(hit.direction, hit.normal, eta, &refracted)) {  // total internal reflection
      ++counts_.reflection;
      through = TraceRay(Spawn(hit, false), mirror, depth + 1, hit.coneWidth);
    } else {
      ++counts_.refraction;
      through = TraceRay(Spawn(hit, true), refracted, depth + 1, hit.coneWidth);
    }
    color = color * (1.0f - transmitted) + through * (coat > 0 ? transmitted * (1.0f - coat) : transmitted);
  }
  if (coat > 0 && hit.pbr.clearcoatRoughness < PbrMaterial::kMirrorRoughness) {
    ++counts_.reflection;
    color += TraceRay(Spawn(hit, false), Reflect(hit.direction, hit.pbr.clearcoatNormal), depth + 1, hit.coneWidth) * coat;
  }
  // A blended surface covers alpha of the ray; the rest goes straight on past it.
  if (material.blends && hit.pbr.alpha < 1) {
    ++counts_.refraction;
    const Float3 behind = TraceRay(Spawn(hit, true), hit.direction, depth + 1, hit.coneWidth);
    color = color * hit.pbr.alpha + behind * (1.0f - hit.pbr.alpha);
  }
  return color;
}

float Tracer::PixelTracer::BlendTransmittance(Float3 start, Float3 direction, float distance) {
  // Only blended surfaces lie on the way (the occlusion query found nothing else): each
  // closest hit is one of them.
  constexpr int kMaxLayers = 64;
  float through = 1;
  Float3 origin = start;
  float left = distance;
  for (int layer = 0; layer < kMaxLayers && through > 0; ++layer) {
    const std::optional<RawHit> raw = ClosestHit(origin, direction, left);
    if (!raw) break;
    const SurfaceHit hit = MakeHit(origin, direction, *raw, 0.0f);
    const ShadingMaterial& m = (*frame_.materials)[hit.material];
    if (!m.pbr || !m.gltf.blends) return 0;  // not a blended surface after all: it blocks
    through *= 1.0f - hit.pbr.alpha;
    origin = Spawn(hit, true);
    left = distance - Length(origin - start);
    if (!(left > 0)) break;
  }
  return through;
}

Float3 Tracer::PixelTracer::TriangleTangent(const ShapeShading& shape, const RawHit& raw, int shapeIndex,
                                            float* handedness) const {
  const auto& corner = shape.triangles[raw.primitiveId];
  const std::array<float, 2>* uvs = shape.pbr->normalTexture.texCoord == 0 ? shape.uvs : shape.uvs1;
  const std::vector<Vec3>& vertices = scene_.shapes[static_cast<size_t>(shapeIndex)].Mesh().vertices;
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

Float3 Tracer::PixelTracer::AmbientPbr(const SurfaceHit& hit, const ShadingMaterial& m) const {
  const PbrSurface& s = hit.pbr;
  if (m.gltf.unlit) return s.baseColor;
  // A uniform sky of radiance `ambient` reflects about the diffuse colour and f0 of it.
  const Float3 reflected = s.baseColor * (1.0f - s.metallic) + SurfaceF0(s, m.gltf.constants);
  if (s.clearcoat > 0) {
    // A coat reflects its share of the sky whole, and dims what lies beneath it, emission too.
    const float coat = ClearcoatWeight(s, -hit.direction);
    return (reflected * (1.0f - coat) + Float3{coat, coat, coat}) * (frame_.ambient * s.occlusion) +
           s.emission * (1.0f - coat);
  }
  return reflected * (frame_.ambient * s.occlusion) + s.emission;
}

Float3 Tracer::PixelTracer::PbrLight(const SurfaceHit& hit, const ShadingMaterial& m, Float3 direction) const {
  return PbrReflected(hit.pbr, m.gltf.constants, direction, hit.normal, -hit.direction);
}

}  // namespace tcfarm
