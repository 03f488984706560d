// glTF's BRDF against its closed forms: the formulas of the specification's Appendix B,
// written out in the test, and a traced frame of a glTF material under one light.
#include "worker/trace/materials/gltf_brdf.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "worker/tracing.h"

namespace tcfarm {
namespace {

constexpr double kPi = 3.14159265358979323846;

// Appendix B, in double, for a light at angle theta from the normal and a viewer along it.
double ReflectedByFormula(double base, double metallic, double roughness, double theta) {
  const double nDotL = std::cos(theta), nDotV = 1;
  const double hx = std::sin(theta), hz = std::cos(theta) + 1, hLength = std::sqrt(hx * hx + hz * hz);
  const double nDotH = hz / hLength, vDotH = hz / hLength;
  const double alpha = roughness * roughness, a2 = alpha * alpha;
  const double d = a2 / (kPi * std::pow(nDotH * nDotH * (a2 - 1) + 1, 2));
  const double v = 0.5 / (nDotL * std::sqrt(nDotV * nDotV * (1 - a2) + a2) + nDotV * std::sqrt(nDotL * nDotL * (1 - a2) + a2));
  auto schlick = [&](double f0) { return f0 + (1 - f0) * std::pow(1 - vDotH, 5); };
  const double dielectric = (1 - schlick(0.04)) * base / kPi + schlick(0.04) * d * v;
  const double metal = schlick(base) * d * v;
  return ((1 - metallic) * dielectric + metallic * metal) * nDotL;
}

TEST(GltfBrdfTest, MatchesAppendixB) {
  for (double metallic : {0.0, 0.5, 1.0}) {
    for (double roughness : {0.3, 0.6, 1.0}) {
      for (double theta : {0.0, 0.4, 1.0}) {
        PbrSurface surface;
        surface.baseColor = {0.7f, 0.7f, 0.7f};
        surface.metallic = static_cast<float>(metallic);
        surface.roughness = static_cast<float>(roughness);
        const Float3 light{static_cast<float>(std::sin(theta)), 0, static_cast<float>(std::cos(theta))};
        const Float3 got = PbrReflected(surface, PbrConstants{}, light, {0, 0, 1}, {0, 0, 1});
        const double want = ReflectedByFormula(0.7, metallic, roughness, theta);
        EXPECT_NEAR(got.x, want, 2e-5 + 1e-4 * want) << "metallic " << metallic << " roughness " << roughness
                                                      << " theta " << theta;
      }
    }
  }
}

TEST(GltfBrdfTest, APerfectlySmoothSurfaceStaysFinite) {
  PbrSurface surface;
  surface.baseColor = {1, 1, 1};
  surface.roughness = 0;
  const Float3 got = PbrReflected(surface, PbrConstants{}, {0, 0, 1}, {0, 0, 1}, {0, 0, 1});
  EXPECT_TRUE(std::isfinite(got.x) && got.x > 0) << got.x;
}

TEST(GltfBrdfTest, NoLightFromBehindTheSurface) {
  PbrSurface surface;
  const Float3 got = PbrReflected(surface, PbrConstants{}, {0, 0, -1}, {0, 0, 1}, {0, 0, 1});
  EXPECT_EQ(got.x, 0.0f);
}

// A quad with a glTF material facing the camera, lit head-on by a point light behind the
// camera: the centre pixel is the BRDF's closed form times the light's intensity over the
// squared distance, plus the ambient share of (diffuse colour + f0).
TEST(GltfBrdfTest, ATracedPixelIsTheClosedForm) {
  const Scene scene = ParseScene(R"({"camera": {"position": [0, 0, 4], "look_at": [0, 0, 0]},
      "lights": [{"type": "point", "position": [0, 0, 2], "intensity": [8, 8, 8]}],
      "materials": {"clay": {"pbr": {"base_color": [0.5, 0.25, 1], "metallic": 0, "roughness": 1}}},
      "shapes": [{"type": "quad", "corner": [-1, -1, 0], "edge_u": [2, 0, 0], "edge_v": [0, 2, 0], "material": "clay"}],
      "render": {"width": 9, "height": 9}})");
  EmbreeDevice device;
  TracingThreads threads(1);
  Tracer tracer(device, scene, threads);
  std::vector<float> rgb(9 * 9 * 3);
  tracer.TraceFrame(0, rgb.data());
  const double irradiance = 8.0 / (2.0 * 2.0);
  const double specular = 0.04 * (1 / kPi) * 0.25;  // F * D * V at V = L = N, roughness 1
  const double base[3] = {0.5, 0.25, 1};
  for (int c = 0; c < 3; ++c) {
    const double want = 0.05 * (base[c] + 0.04) + ((1 - 0.04) * base[c] / kPi + specular) * irradiance;
    EXPECT_NEAR(rgb[3 * (4 * 9 + 4) + c], want, 1e-5) << "channel " << c;
  }
}

// An unlit material shows its base colour and casts no shadow ray; emission adds its
// factor times its strength.
TEST(GltfBrdfTest, UnlitShowsItsColourAndEmissionItsStrength) {
  auto render = [](const std::string& pbr, uint64_t* shadowRays) {
    const Scene scene = ParseScene(R"({"camera": {"position": [0, 0, 4], "look_at": [0, 0, 0]},
        "lights": [{"type": "point", "position": [0, 0, 2], "intensity": [8, 8, 8]}],
        "materials": {"m": {"pbr": )" + pbr + R"(}},
        "shapes": [{"type": "quad", "corner": [-1, -1, 0], "edge_u": [2, 0, 0], "edge_v": [0, 2, 0], "material": "m"}],
        "render": {"width": 9, "height": 9, "ambient": 0}})");
    EmbreeDevice device;
    TracingThreads threads(1);
    Tracer tracer(device, scene, threads);
    std::vector<float> rgb(9 * 9 * 3);
    tracer.TraceFrame(0, rgb.data());
    *shadowRays = tracer.Counts().shadow;
    return rgb[3 * (4 * 9 + 4)];
  };
  uint64_t shadowRays = 0;
  EXPECT_FLOAT_EQ(render(R"({"base_color": [0.3, 0.3, 0.3], "unlit": true})", &shadowRays), 0.3f);
  EXPECT_EQ(shadowRays, 0u);
  const float lit = render(R"({"base_color": [0, 0, 0], "metallic": 0})", &shadowRays);
  EXPECT_GT(shadowRays, 0u);
  const float glowing =
      render(R"({"base_color": [0, 0, 0], "metallic": 0, "emissive": [0.5, 0.5, 0.5], "emissive_strength": 4})", &shadowRays);
  EXPECT_NEAR(glowing - lit, 2.0f, 1e-5f);
}

// KHR_materials_clearcoat, in double, over a dielectric base (metallic 0): light at
// thetaL and viewer at thetaV on either side of the normal, in one plane. The base's
// Appendix B term and the coat's GGX lobe (f0 0.04, its own roughness) mixed by
// w = clearcoat * Schlick(0.04, 1, NdotV).
double CoatedByFormula(double base, double roughness, double clearcoat, double coatRoughness, double thetaL,
                       double thetaV) {
  const double nDotL = std::cos(thetaL), nDotV = std::cos(thetaV);
  const double hx = std::sin(thetaL) - std::sin(thetaV), hz = nDotL + nDotV, hLength = std::sqrt(hx * hx + hz * hz);
  const double nDotH = hz / hLength, vDotH = (-std::sin(thetaV) * hx + nDotV * hz) / hLength;
  auto schlick = [](double f0, double cosine) { return f0 + (1 - f0) * std::pow(1 - cosine, 5); };
  auto ggx = [&](double r) {  // D * V
    const double alpha = r * r, a2 = alpha * alpha;
    const double d = a2 / (kPi * std::pow(nDotH * nDotH * (a2 - 1) + 1, 2));
    return d * 0.5 / (nDotL * std::sqrt(nDotV * nDotV * (1 - a2) + a2) + nDotV * std::sqrt(nDotL * nDotL * (1 - a2) + a2));
  };
  const double f = schlick(0.04, vDotH);
  const double layer = ((1 - f) * base / kPi + f * ggx(roughness)) * nDotL;
  const double coat = ggx(coatRoughness) * nDotL;
  const double w = clearcoat * schlick(0.04, nDotV);
  return (1 - w) * layer + w * coat;
}

TEST(GltfBrdfTest, ClearcoatMatchesItsClosedForm) {
  for (double clearcoat : {0.0, 0.5, 1.0}) {
    for (double coatRoughness : {0.1, 0.4, 0.8}) {
      for (double thetaV : {0.0, 0.7, 1.3}) {
        PbrSurface surface;
        surface.baseColor = {0.8f, 0.8f, 0.8f};
        surface.metallic = 0;
        surface.roughness = 0.9f;
        surface.clearcoat = static_cast<float>(clearcoat);
        surface.clearcoatRoughness = static_cast<float>(coatRoughness);
        surface.clearcoatNormal = {0, 0, 1};
        const double thetaL = 0.5;
        const Float3 light{static_cast<float>(std::sin(thetaL)), 0, static_cast<float>(std::cos(thetaL))};
        const Float3 viewer{static_cast<float>(-std::sin(thetaV)), 0, static_cast<float>(std::cos(thetaV))};
        const double got = PbrReflected(surface, PbrConstants{}, light, {0, 0, 1}, viewer).x;
        const double want = CoatedByFormula(0.8, 0.9, clearcoat, coatRoughness, thetaL, thetaV);
        EXPECT_NEAR(got, want, 2e-5 + 2e-4 * want)
            << "clearcoat " << clearcoat << " coat roughness " << coatRoughness << " thetaV " << thetaV;
      }
    }
  }
}

// The head-on quad of ATracedPixelIsTheClosedForm under a rough coat: seen along the normal
// the coat takes w = clearcoat * 0.04 of everything beneath it (ambient, lights, emission)
// and adds its own lobe, D * V = 1 / (4 pi alpha^2) at N = L = V.
TEST(GltfBrdfTest, ACoatedTracedPixelIsTheClosedForm) {
  const Scene scene = ParseScene(R"({"camera": {"position": [0, 0, 4], "look_at": [0, 0, 0]},
      "lights": [{"type": "point", "position": [0, 0, 2], "intensity": [8, 8, 8]}],
      "materials": {"lacquer": {"pbr": {"base_color": [0.5, 0.25, 1], "metallic": 0, "roughness": 1,
                                        "emissive": [0.1, 0.2, 0.3], "clearcoat": 0.5, "clearcoat_roughness": 0.5}}},
      "shapes": [{"type": "quad", "corner": [-1, -1, 0], "edge_u": [2, 0, 0], "edge_v": [0, 2, 0], "material": "lacquer"}],
      "render": {"width": 9, "height": 9}})");
  EmbreeDevice device;
  TracingThreads threads(1);
  Tracer tracer(device, scene, threads);
  std::vector<float> rgb(9 * 9 * 3);
  tracer.TraceFrame(0, rgb.data());
  const double irradiance = 8.0 / (2.0 * 2.0);
  const double w = 0.5 * 0.04, coatAlpha = 0.5 * 0.5;
  const double coatLobe = 1 / (4 * kPi * coatAlpha * coatAlpha);
  const double specular = 0.04 * (1 / kPi) * 0.25;
  const double base[3] = {0.5, 0.25, 1}, emissive[3] = {0.1, 0.2, 0.3};
  for (int c = 0; c < 3; ++c) {
    const double ambient = 0.05 * ((1 - w) * (base[c] + 0.04) + w);
    const double lit = ((1 - w) * ((1 - 0.04) * base[c] / kPi + specular) + w * coatLobe) * irradiance;
    EXPECT_NEAR(rgb[3 * (4 * 9 + 4) + c], ambient + lit + (1 - w) * emissive[c], 1e-5) << "channel " << c;
  }
}

// A smooth coat mirrors what it faces, weighted by clearcoat * Fresnel: a black, rough
// base before a glowing quad behind the camera shows w = clearcoat * 0.04 of its glow.
TEST(GltfBrdfTest, ASmoothCoatMirrorsByItsWeight) {
  const Scene scene = ParseScene(R"({"camera": {"position": [0, 0, 4], "look_at": [0, 0, 0]},
      "materials": {"coated": {"pbr": {"base_color": [0, 0, 0], "metallic": 0, "roughness": 1, "clearcoat": 0.5}},
                    "glow": {"pbr": {"base_color": [0, 0, 0], "metallic": 0, "roughness": 1, "emissive": [1, 1, 1]}}},
      "shapes": [{"type": "quad", "corner": [-1, -1, 0], "edge_u": [2, 0, 0], "edge_v": [0, 2, 0], "material": "coated"},
                 {"type": "quad", "corner": [-9, -9, 6], "edge_u": [0, 18, 0], "edge_v": [18, 0, 0], "material": "glow"}],
      "render": {"width": 9, "height": 9, "ambient": 0}})");
  EmbreeDevice device;
  TracingThreads threads(1);
  Tracer tracer(device, scene, threads);
  std::vector<float> rgb(9 * 9 * 3);
  tracer.TraceFrame(0, rgb.data());
  EXPECT_NEAR(rgb[3 * (4 * 9 + 4)], 0.5 * 0.04, 1e-6);
  EXPECT_GT(tracer.Counts().reflection, 0u);
}

// A material no shape uses costs no decoding: its texture, never fetched here, is not read.
TEST(GltfBrdfTest, TexturesOfUnusedMaterialsAreNotLoaded) {
  auto scene = [](const std::string& material) {
    return ParseScene(R"({"camera": {"position": [0, 0, 4], "look_at": [0, 0, 0]},
        "materials": {"clay": {"pbr": {"base_color": [0.5, 0.5, 0.5]}},
                      "printed": {"pbr": {"base_color_texture": {"asset": ")" + std::string(64, 'a') + R"("}}}},
        "shapes": [{"type": "quad", "corner": [-1, -1, 0], "edge_u": [2, 0, 0], "edge_v": [0, 2, 0],
                    "material": ")" + material + R"("}],
        "render": {"width": 9, "height": 9}})");
  };
  EmbreeDevice device;
  TracingThreads threads(1);
  const Scene unused = scene("clay");
  EXPECT_NO_THROW(Tracer(device, unused, threads));
  const Scene used = scene("printed");
  EXPECT_THROW(Tracer(device, used, threads), TextureError);
}

}  // namespace
}  // namespace tcfarm
