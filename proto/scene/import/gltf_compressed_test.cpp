// Compressed glTF geometry (KHR_draco_mesh_compression, EXT_meshopt_compression) and
// KHR_mesh_quantization: files written by the libraries' own encoders import as the plain
// file does, and damaged compressed data is refused with the pointer of what holds it.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>

#include "proto/scene/import/import_budget.h"
#include "proto/scene/import/scene_import.h"
#include "tests/support/cpp/skinned_compressed_gltf.h"

namespace tcfarm {
namespace {

using compressed_gltf::DracoGltf;
using compressed_gltf::DracoOptions;
using compressed_gltf::MakeSphere;
using compressed_gltf::MeshoptGltf;
using compressed_gltf::PlainGltf;
using nlohmann::json;

Scene Import(const json& gltf) { return ImportSceneBytes(gltf.dump(), "gltf"); }

const TriangleMesh& OnlyMesh(const Scene& scene) {
  EXPECT_EQ(scene.shapes.size(), 1u);
  return scene.shapes.at(0).Mesh();
}

void ExpectRefused(const json& gltf, const std::string& pointer, const std::string& problem) {
  const std::string what = ErrorOf([&] { Import(gltf); });
  EXPECT_EQ(what.find("scene" + pointer + ": the gltf scene: "), 0u) << what;
  EXPECT_NE(what.find(problem), std::string::npos) << what;
}

// The largest distance between corresponding vertices (positions, normals, uvs).
double LargestDifference(const TriangleMesh& a, const TriangleMesh& b) {
  double largest = 0;
  for (size_t v = 0; v < a.vertices.size(); ++v) {
    for (int c = 0; c < 3; ++c) {
      largest = std::max({largest, std::fabs(a.vertices[v][c] - b.vertices[v][c]),
                          std::fabs(a.normals[v][c] - b.normals[v][c])});
    }
    for (int c = 0; c < 2; ++c) largest = std::max(largest, std::fabs(a.uvs[v][c] - b.uvs[v][c]));
  }
  return largest;
}

TEST(GltfCompressedTest, LosslessDracoImportsAsThePlainFile) {
  const auto sphere = MakeSphere(12, 24);
  const Scene plain = Import(PlainGltf(sphere));
  const Scene draco = Import(DracoGltf(sphere));
  EXPECT_EQ(OnlyMesh(draco).triangles.size(), 2u * 12 * 24);
  EXPECT_EQ(SerializeScene(draco), SerializeScene(plain));
}

// In a GLB the compressed data lies in the BIN chunk; Draco's indices accessor without a
// buffer view needs a stand-in in the JSON chunk, which must then be rebuilt.
TEST(GltfCompressedTest, DracoAndMeshoptGlbImportAsThePlainFile) {
  const auto sphere = MakeSphere(12, 24);
  const std::string plain = SerializeScene(Import(PlainGltf(sphere)));
  EXPECT_EQ(SerializeScene(ImportSceneBytes(compressed_gltf::Glb(DracoGltf(sphere)), "gltf")), plain);
  const Scene meshopt = ImportSceneBytes(compressed_gltf::Glb(MeshoptGltf(sphere)), "gltf");
  EXPECT_EQ(OnlyMesh(meshopt).vertices, OnlyMesh(Import(PlainGltf(sphere))).vertices);
}

// JOINTS_0 and WEIGHTS_0 as Draco generic attributes: the skin and its animation as plain.
TEST(GltfCompressedTest, SkinnedDracoImportsAsThePlainFile) {
  const auto sphere = MakeSphere(8, 16);
  const Scene plain = Import(compressed_gltf::SkinnedPlainGltf(sphere));
  ASSERT_EQ(plain.shapes.size(), 1u);
  ASSERT_TRUE(plain.shapes[0].deformation && plain.shapes[0].deformation->hasSkin);
  ASSERT_TRUE(plain.shapes[0].deformation->IsAnimated());
  EXPECT_EQ(SerializeScene(Import(compressed_gltf::SkinnedDracoGltf(sphere))), SerializeScene(plain));
}

TEST(GltfCompressedTest, QuantizedEdgebreakerDracoKeepsTheSurfaceWithinItsQuantization) {
  const auto sphere = MakeSphere(12, 24);
  const TriangleMesh plain = OnlyMesh(Import(PlainGltf(sphere)));
  const TriangleMesh draco = OnlyMesh(Import(DracoGltf(sphere, DracoOptions{false, 14})));
  ASSERT_EQ(draco.triangles.size(), plain.triangles.size());
  ASSERT_EQ(draco.colors.size(), draco.vertices.size());
  // Edgebreaker renumbers vertices: every decoded one lies within 14-bit quantization of the
  // sphere (radius 1, a range of 2: steps of 2 / 2^14) and its normal points the same way.
  for (size_t v = 0; v < draco.vertices.size(); ++v) {
    const Vec3& p = draco.vertices[v];
    EXPECT_NEAR(std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]), 1.0, 2.0 / (1 << 14)) << v;
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(draco.normals[v][c], p[c], 2e-3) << v;
  }
}

// The scene with each triangle started at its smallest index (the same triangle, the same winding).
std::string WithTrianglesRotated(Scene scene) {
  for (Shape& shape : scene.shapes) {
    for (auto& t : shape.mesh.triangles) std::rotate(t.begin(), std::min_element(t.begin(), t.end()), t.end());
  }
  return SerializeScene(scene);
}

// meshopt's triangle codec may start a triangle at another of its corners; all else is exact.
TEST(GltfCompressedTest, MeshoptImportsAsThePlainFileWithoutItsFallbackBuffer) {
  const auto sphere = MakeSphere(12, 24);
  EXPECT_EQ(WithTrianglesRotated(Import(MeshoptGltf(sphere))), WithTrianglesRotated(Import(PlainGltf(sphere))));
}

TEST(GltfCompressedTest, MeshoptFiltersDecodeWithinTheirPrecision) {
  const auto sphere = MakeSphere(12, 24);
  const TriangleMesh plain = OnlyMesh(Import(PlainGltf(sphere)));
  const TriangleMesh filtered = OnlyMesh(Import(MeshoptGltf(sphere, true)));
  ASSERT_EQ(filtered.vertices.size(), plain.vertices.size());
  const double difference = LargestDifference(filtered, plain);
  EXPECT_GT(difference, 0);             // the filters are lossy: the test reads their output
  EXPECT_LT(difference, 2.0 / 127 + 1e-6);  // 8-bit octahedral normals
}

TEST(GltfCompressedTest, TruncatedDracoDataIsRefusedAtItsExtension) {
  json gltf = DracoGltf(MakeSphere(6, 12));
  gltf["bufferViews"][0]["byteLength"] = gltf["bufferViews"][0]["byteLength"].get<size_t>() / 2;
  ExpectRefused(gltf, "/meshes/0/primitives/0/extensions/KHR_draco_mesh_compression", "do not decode as a Draco mesh");
}

TEST(GltfCompressedTest, DamagedDracoDataNeverCrashes) {
  const auto sphere = MakeSphere(6, 12);
  std::vector<int> ids;
  const std::string good = compressed_gltf::DracoBytes(sphere, DracoOptions{false, 11}, &ids);
  // Each of the first bytes (header, connectivity) flipped in turn, and the data cut short at
  // each of them: every file either imports or is refused as bad input, never anything else.
  size_t refused = 0;
  for (size_t i = 0; i < 96 && i < good.size(); ++i) {
    std::string flipped = good;
    flipped[i] = static_cast<char>(flipped[i] ^ 0x5A);
    for (const std::string& bytes : {flipped, good.substr(0, i)}) {
      try {
        Import(compressed_gltf::WithDraco(sphere, bytes, ids));
      } catch (const SceneError&) {
        ++refused;
      }
    }
  }
  EXPECT_GT(refused, 96u);  // every cut at least
}

TEST(GltfCompressedTest, DracoCountsMustMatchTheDecodedMesh) {
  json gltf = DracoGltf(MakeSphere(6, 12));
  gltf["accessors"][0]["count"] = 5;
  ExpectRefused(gltf, "/accessors/0/count", "5 elements where the Draco mesh decodes to");
}

TEST(GltfCompressedTest, DracoAttributeIdsMustExist) {
  json gltf = DracoGltf(MakeSphere(6, 12));
  gltf["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"]["attributes"]["NORMAL"] = 77;
  ExpectRefused(gltf, "/meshes/0/primitives/0/extensions/KHR_draco_mesh_compression/attributes/NORMAL",
                "Draco attribute id 77");
}

TEST(GltfCompressedTest, TruncatedMeshoptDataIsRefusedAtItsExtension) {
  json gltf = MeshoptGltf(MakeSphere(6, 12));
  auto& extension = gltf["bufferViews"][0]["extensions"]["EXT_meshopt_compression"];
  extension["byteLength"] = extension["byteLength"].get<size_t>() / 2;
  ExpectRefused(gltf, "/bufferViews/0/extensions/EXT_meshopt_compression", "do not decode as meshopt ATTRIBUTES");
}

TEST(GltfCompressedTest, MeshoptLayoutIsCheckedBeforeDecoding) {
  json gltf = MeshoptGltf(MakeSphere(6, 12));
  gltf["bufferViews"][0]["extensions"]["EXT_meshopt_compression"]["filter"] = "QUATERNION";
  ExpectRefused(gltf, "/bufferViews/0/extensions/EXT_meshopt_compression/filter", "filter \"QUATERNION\"");
  gltf = MeshoptGltf(MakeSphere(6, 12));
  gltf["bufferViews"][0]["extensions"]["EXT_meshopt_compression"]["count"] = 1;
  ExpectRefused(gltf, "/bufferViews/0", "over compressed data of 1 elements");
}

TEST(GltfCompressedTest, APlainViewIntoAFallbackBufferIsRefused) {
  json gltf = MeshoptGltf(MakeSphere(6, 12));
  gltf["bufferViews"][0].erase("extensions");
  ExpectRefused(gltf, "/bufferViews/0/buffer", "fallback without data");
}

// A small file whose meshopt data decodes to far more than its bytes: all-zero attributes
// cost a few bits per 16 elements.
// Draco compresses a real mesh 20 to 30 times: a quantized sphere of 2 million triangles
// decodes to 60 MB from 2.4 MB, past 16 bytes per byte and the fixed allowance.
TEST(GltfCompressedTest, AQuantizedDracoMeshOfTwoMillionTrianglesFitsTheBudget) {
  const json gltf = DracoGltf(MakeSphere(1000, 1000), DracoOptions{false, 14});
  EXPECT_EQ(OnlyMesh(Import(gltf)).triangles.size(), 2'000'000u);
}

TEST(GltfCompressedTest, DecodedBytesCountAgainstTheValueBudget) {
  const size_t count = 3'000'000, stride = 16;
  std::vector<unsigned char> out(meshopt_encodeVertexBufferBound(count, stride));
  const std::vector<unsigned char> zeros(count * stride, 0);
  out.resize(meshopt_encodeVertexBuffer(out.data(), out.size(), zeros.data(), count, stride));
  const std::string bytes(out.begin(), out.end());
  ASSERT_LT(bytes.size(), 2'000'000u);
  json gltf = {{"asset", {{"version", "2.0"}}},
               {"buffers", {{{"byteLength", bytes.size()}, {"uri", compressed_gltf::DataUri(bytes)}}}},
               {"bufferViews",
                {{{"buffer", 0},
                  {"byteLength", count * stride},
                  {"extensions",
                   {{"EXT_meshopt_compression",
                     {{"buffer", 0}, {"byteLength", bytes.size()}, {"byteStride", stride}, {"count", count},
                      {"mode", "ATTRIBUTES"}}}}}}}}};
  ExpectRefused(gltf, "/bufferViews/0/extensions/EXT_meshopt_compression",
                "decoding it brings the values read and decoded from the file to 48000000 bytes");
}

// Within the coordinator's import budget (import_budget.h) an import charges what it is
// about to decode to its thread's reservation first: a budget too small for it refuses the
// file, however far inside its per-file limits.
TEST(GltfCompressedTest, DecodingIsChargedToTheImportBudgetBeforehand) {
  const auto sphere = MakeSphere(100, 100);
  const uint64_t vertices = sphere.Vertices();
  for (const json& gltf : {MeshoptGltf(sphere), DracoGltf(sphere)}) {
    ImportBudget budget(uint64_t{1} << 30);
    const uint64_t held = WithinImportBudget(&budget, 0, [&] {
      Import(gltf);
      return budget.Stats().reservedBytes;
    });
    // At least the positions', normals' and texture coordinates' values, and the mesh's.
    EXPECT_GE(held, 2 * 8 * sizeof(double) * vertices);
    EXPECT_EQ(budget.Stats().reservedBytes, 0u);
    ImportBudget small(held / 2);
    EXPECT_THROW(WithinImportBudget(&small, 0, [&] { Import(gltf); }), ImportTooLargeError);
    EXPECT_EQ(small.Stats().reservedBytes, 0u);
  }
}

// KHR_mesh_quantization: SHORT positions as they are, normalized BYTE normals and
// UNSIGNED_SHORT texture coordinates mapped into [-1, 1] and [0, 1].
TEST(GltfCompressedTest, QuantizedAttributesImport) {
  const std::vector<int16_t> positions = {0, 0, 0, 0, 300, 0, 0, 0, 0, -300, 0, 0};  // stride 8
  const std::vector<int8_t> normals = {0, 0, 127, 0, 0, 0, -127, 0, 0, 0, 127, 0};  // stride 4
  const std::vector<uint16_t> uvs = {0, 0, 65535, 0, 0, 32768};
  const std::string data = compressed_gltf::BytesOf(positions) + compressed_gltf::BytesOf(normals) +
                           compressed_gltf::BytesOf(uvs);
  json gltf = {
      {"asset", {{"version", "2.0"}}},
      {"extensionsUsed", {"KHR_mesh_quantization"}},
      {"extensionsRequired", {"KHR_mesh_quantization"}},
      {"scene", 0},
      {"scenes", {{{"nodes", {0}}}}},
      {"nodes", {{{"mesh", 0}, {"scale", {0.01, 0.01, 0.01}}}}},
      {"meshes", {{{"primitives", {{{"attributes", {{"POSITION", 0}, {"NORMAL", 1}, {"TEXCOORD_0", 2}}}}}}}}},
      {"buffers", {{{"byteLength", data.size()}, {"uri", compressed_gltf::DataUri(data)}}}},
      {"bufferViews",
       {{{"buffer", 0}, {"byteLength", 24}, {"byteStride", 8}},
        {{"buffer", 0}, {"byteOffset", 24}, {"byteLength", 12}, {"byteStride", 4}},
        {{"buffer", 0}, {"byteOffset", 36}, {"byteLength", 12}}}},
      {"accessors",
       {{{"bufferView", 0}, {"componentType", 5122}, {"type", "VEC3"}, {"count", 3}},
        {{"bufferView", 1}, {"componentType", 5120}, {"normalized", true}, {"type", "VEC3"}, {"count", 3}},
        {{"bufferView", 2}, {"componentType", 5123}, {"normalized", true}, {"type", "VEC2"}, {"count", 3}}}}};
  const TriangleMesh mesh = OnlyMesh(Import(gltf));
  EXPECT_EQ(mesh.vertices[1][0], 300);
  EXPECT_EQ(mesh.vertices[2][1], -300);
  EXPECT_EQ(mesh.normals[0][2], 1.0);
  EXPECT_EQ(mesh.normals[1][2], -1.0);
  EXPECT_EQ(mesh.uvs[1][0], 1.0);
  EXPECT_DOUBLE_EQ(mesh.uvs[2][1], 32768.0 / 65535);
  gltf["accessors"][1]["normalized"] = false;
  ExpectRefused(gltf, "/accessors/1/normalized", "integer normals that are not normalized");
}

}  // namespace
}  // namespace tcfarm
