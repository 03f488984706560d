// The Whitted model's shading (proto/scene/material.h, Phong): a diffuse colour (times its
// texture and the mesh's vertex colours), a Phong highlight, an ambient term and its own
// emission, and mirror reflection and refraction weighed against the rest. All inline: it
// is asked for every hit and light, where a call would cost more than the work.
#pragma once

#include <cmath>
#include <memory>

#include "proto/scene/scene.h"
#include "worker/embree/surface_filter.h"
#include "worker/trace/barycentric.h"
#include "worker/trace/float3.h"
#include "worker/trace/textures.h"

namespace tcfarm {

struct PhongSurface {
  Float3 diffuse;  // the material's diffuse colour here (its texture's, where it has one)
};

struct PhongShading {
  using Surface = PhongSurface;
  Float3 diffuse, specular;
  float shininess, reflectivity, transparency, indexOfRefraction;
  Float3 emission;
  bool emits;
  // Read at the hit's coordinates alone (level 0): it needs no mip levels.
  const TextureImage* texture = nullptr;

  // Its texture is decoded whether or not a shape uses it (`used`), so that an image that
  // cannot be read fails the scene alike.
  PhongShading(const Phong& m, const TextureLoader& load, bool /*used*/)
      : diffuse(ToFloat3(m.diffuse)),
        specular(ToFloat3(m.specular)),
        shininess(static_cast<float>(m.shininess)),
        reflectivity(static_cast<float>(m.reflectivity)),
        transparency(static_cast<float>(m.transparency)),
        indexOfRefraction(static_cast<float>(m.indexOfRefraction)),
        emission(ToFloat3(m.emission)),
        emits(m.emission != Vec3{}) {
    if (!m.diffuseTexture) return;
    Texture fullImageOnly = *m.diffuseTexture;
    fullImageOnly.mipmaps = false;
    texture = load(fullImageOnly, TextureImage::Encoding::kSrgb);
  }
  // Every hit counts, on either side: Phong has no alpha.
  static std::unique_ptr<SurfaceRule> SurfaceRuleFor(const Shape&, const Phong&, const ShapeUvSets&,
                                                     const TextureLoader&) {
    return nullptr;
  }

  bool ReadsTexCoord(int set) const { return set == 0 && texture; }
  bool ReadsTangents() const { return false; }
  bool ReadsTriangles() const { return false; }  // only for its texture or vertex colours
  // Whether its colour varies over the shape (texture or vertex colours).
  template <typename ShapeShading>
  bool VariesOver(const ShapeShading& shape) const { return shape.VariesDiffuse(); }
  bool Unlit() const { return false; }
  bool Blends() const { return false; }
  float Coverage(const Surface&) const { return 1; }
  bool MirrorsOrRefracts() const { return reflectivity != 0 || transparency != 0; }

  template <typename Tracer>
  void Shade(const Tracer&, const typename Tracer::ShapeShading& shape, const typename Tracer::RawHit& raw,
             typename Tracer::SurfaceHit& hit) const {
    hit.surface = Surface{shape.VariesDiffuse() ? DiffuseAt(shape, raw) : diffuse};
  }
  // The diffuse colour at the hit: the material's, times its texture at the hit's
  // interpolated texture coordinates where the shape has them, times its vertex colour.
  template <typename ShapeShading, typename RawHit>
  Float3 DiffuseAt(const ShapeShading& shape, const RawHit& raw) const {
    const auto& corner = shape.triangles[raw.primitiveId];
    Float3 color = diffuse;
    if (shape.uvs) {
      const std::array<float, 2> uv = AtBarycentric(shape.uvs, corner, raw.u, raw.v);
      color = color * texture->Sample(uv[0], uv[1]);
    }
    if (shape.colors) color = color * AtBarycentric(shape.colors, corner, raw.u, raw.v);
    return color;
  }
  // What the surface shows with no light: the ambient share of its diffuse colour (so
  // surfaces in shadow keep their shape), and its own emission.
  Float3 Ambient(const Surface& s, Float3 /*arriving*/, float ambient) const {
    const Float3 lit = s.diffuse * ambient;
    return emits ? lit + emission : lit;
  }
  // Light of unit intensity arriving from unit direction `towardLight` at a surface of
  // unit `normal`, seen by a ray arriving along unit `arriving`.
  Float3 Reflected(const Surface& s, Float3 towardLight, Float3 normal, Float3 arriving) const {
    float cosine = Dot(towardLight, normal);
    Float3 color = s.diffuse * cosine;
    if (specular.x > 0 || specular.y > 0 || specular.z > 0) {
      float highlight = Dot(Reflect(-towardLight, normal), -arriving);
      if (highlight > 0) color += specular * std::pow(highlight, shininess);
    }
    return color;
  }
  // Local shading weighted against mirror reflection and refraction, Whitted style.
  template <typename Tracer>
  Float3 Combine(Tracer& tracer, const typename Tracer::SurfaceHit& hit, const Surface&, Float3 local,
                 int depth) const {
    Float3 color = local * (1.0f - reflectivity - transparency);
    Float3 mirror = Reflect(hit.direction, hit.normal);
    if (reflectivity > 0) {
      color += tracer.Secondary(hit, false, mirror, depth) * reflectivity;
    }
    if (transparency > 0) {
      float eta = hit.fromInside ? indexOfRefraction : 1.0f / indexOfRefraction;
      Float3 refracted;
      if (!Refract(hit.direction, hit.normal, eta, &refracted)) {  // total internal reflection
        color += tracer.Secondary(hit, false, mirror, depth) * transparency;
      } else {
        color += tracer.Secondary(hit, true, refracted, depth) * transparency;
      }
    }
    return color;
  }
};

}  // namespace tcfarm
