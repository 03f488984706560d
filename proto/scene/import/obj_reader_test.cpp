#include "proto/scene/import/obj_reader.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <string>

namespace tcfarm {
namespace {

using Triangle = std::array<uint32_t, 3>;

ObjReadOptions Options() {
  ObjReadOptions options;
  options.pointer = "/shapes/0/file";
  options.displayName = "model.obj";
  options.triangleBudget = 1000;
  options.triangleLimit = 1000;
  return options;
}

// Options that read material libraries from `libraries` (name -> text).
ObjReadOptions WithLibraries(std::map<std::string, std::string> libraries) {
  ObjReadOptions options = Options();
  options.pointer = "";
  options.readMaterialLibrary = [libraries](const std::string& name, size_t line) {
    auto found = libraries.find(name);
    if (found == libraries.end()) {
      throw SceneError("", "no library " + name + " at line " + std::to_string(line) + "; expected one");
    }
    return found->second;
  };
  return options;
}

double TriangleArea(const TriangleMesh& mesh, const Triangle& t) {
  const Vec3& a = mesh.vertices[t[0]];
  const Vec3& b = mesh.vertices[t[1]];
  const Vec3& c = mesh.vertices[t[2]];
  Vec3 ab{b.x - a.x, b.y - a.y, b.z - a.z};
  Vec3 ac{c.x - a.x, c.y - a.y, c.z - a.z};
  Vec3 n{ab.y * ac.z - ab.z * ac.y, ab.z * ac.x - ab.x * ac.z, ab.x * ac.y - ab.y * ac.x};
  return 0.5 * std::sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
}

// Passes when reading throws a SceneError at `pointer` whose text mentions `mention`.
testing::AssertionResult Fails(const std::string& text, const std::string& mention,
                               const ObjReadOptions& options = Options()) {
  try {
    ReadObj(text, options);
  } catch (const SceneError& error) {
    std::string what = error.what();
    if (error.pointer() != options.pointer) return testing::AssertionFailure() << "pointer of " << what;
    if (what.find(mention) == std::string::npos || what.find("; expected ") == std::string::npos) {
      return testing::AssertionFailure() << "\"" << what << "\" does not mention \"" << mention << "\"";
    }
    return testing::AssertionSuccess();
  }
  return testing::AssertionFailure() << "no SceneError";
}

// --- polygons ----------------------------------------------------------------------------

TEST(ObjReaderTest, QuadsAndConvexPolygonsAreFanned) {
  ObjModel model = ReadObj(
      "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nv 3 0 0\nv 3.5 1 0\nv 2.5 2 0\nv 1.5 1 0\n"
      "f 1 2 3 4\nf 5 6 7 8 9\n",
      Options());
  std::vector<Triangle> expected{{0, 1, 2}, {0, 2, 3}, {4, 5, 6}, {4, 6, 7}, {4, 7, 8}};
  EXPECT_EQ(model.mesh.triangles, expected);
  EXPECT_TRUE(model.mesh.normals.empty());
  EXPECT_TRUE(model.mesh.uvs.empty());
  ASSERT_EQ(model.parts.size(), 1u);
  EXPECT_EQ(model.parts[0].triangleCount, 5u);
  EXPECT_EQ(model.parts[0].material, -1);
}

TEST(ObjReaderTest, ConcavePolygonIsEarClippedInsideItsOutline) {
  // An L, the face starting at (2, 0): a fan from there would cover the notch at (1.5, 1.5).
  //  6---5
  //  |   |
  //  |   4---3
  //  |       |
  //  1-------2
  ObjModel model = ReadObj("v 0 0 0\nv 2 0 0\nv 2 1 0\nv 1 1 0\nv 1 2 0\nv 0 2 0\nf 2 3 4 5 6 1\n", Options());
  ASSERT_EQ(model.mesh.triangles.size(), 4u);
  double area = 0;
  for (const auto& t : model.mesh.triangles) {
    double a = TriangleArea(model.mesh, t);
    EXPECT_GT(a, 0);
    area += a;
  }
  EXPECT_DOUBLE_EQ(area, 3.0);  // the L's area: no triangle covers the notch
}

TEST(ObjReaderTest, TriangulatePolygonFansConvexAndClipsConcave) {
  EXPECT_EQ(TriangulatePolygon({{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}}).size(), 2u);
  // A concave quad (a dart) in the x/z plane, wound either way.
  std::vector<Vec3> dart{{0, 0, 0}, {2, 0, 1}, {0, 0, 2}, {0.5, 0, 1}};
  for (int flip = 0; flip < 2; ++flip) {
    auto triangles = TriangulatePolygon(dart);
    ASSERT_EQ(triangles.size(), 2u);
    TriangleMesh mesh;
    mesh.vertices = dart;
    double area = 0;
    for (const auto& t : triangles) {
      area += TriangleArea(mesh, {static_cast<uint32_t>(t[0]), static_cast<uint32_t>(t[1]),
                                  static_cast<uint32_t>(t[2])});
    }
    EXPECT_DOUBLE_EQ(area, 1.5) << flip;
    std::reverse(dart.begin(), dart.end());
  }
}

// --- normals and texture coordinates --------------------------------------------------------

TEST(ObjReaderTest, NormalsAndUvsAreKeptPerVertex) {
  ObjModel model = ReadObj(
      "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
      "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1 0.5\n"
      "vn 0 0 1\nvn 0 0.6 0.8\n"
      "f 1/1/1 2/2/1 3/3/2 4/4/2\n",
      Options());
  ASSERT_EQ(model.mesh.vertices.size(), 4u);
  ASSERT_EQ(model.mesh.normals.size(), 4u);
  ASSERT_EQ(model.mesh.uvs.size(), 4u);
  EXPECT_EQ(model.mesh.normals[1], (Vec3{0, 0, 1}));
  EXPECT_EQ(model.mesh.normals[2], (Vec3{0, 0.6, 0.8}));
  EXPECT_EQ(model.mesh.uvs[3], (std::array<double, 2>{0, 1}));
}

TEST(ObjReaderTest, PositionUsedWithTwoNormalsIsSplit) {
  // A hard edge: the two faces share positions 2 and 3 but not their normals.
  ObjModel model = ReadObj(
      "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 2 0 1\nvn 0 0 1\nvn 1 0 0\n"
      "f 1//1 2//1 3//1\nf 2//2 4//2 3//2\n",
      Options());
  ASSERT_EQ(model.mesh.vertices.size(), 6u);
  ASSERT_EQ(model.mesh.normals.size(), 6u);
  std::vector<Triangle> expected{{0, 1, 2}, {4, 3, 5}};
  EXPECT_EQ(model.mesh.triangles, expected);
  EXPECT_EQ(model.mesh.vertices[4], model.mesh.vertices[1]);
  EXPECT_EQ(model.mesh.normals[4], (Vec3{1, 0, 0}));
  EXPECT_EQ(model.mesh.normals[3], (Vec3{1, 0, 0}));  // position 4's first use
  EXPECT_EQ(model.mesh.normals[0], (Vec3{0, 0, 1}));
}

TEST(ObjReaderTest, AttributesOnlySomeCornersNameAreDropped) {
  ObjModel model = ReadObj("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\nf 1/1/1 2//1 3/1\n", Options());
  EXPECT_TRUE(model.mesh.normals.empty());
  EXPECT_TRUE(model.mesh.uvs.empty());
  EXPECT_EQ(model.mesh.vertices.size(), 3u);
}

TEST(ObjReaderTest, CoordinatesAreReadExactly) {
  ObjModel model = ReadObj("v 0.123 -1e-7 3.3333333333333335\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", Options());
  EXPECT_EQ(model.mesh.vertices[0], (Vec3{0.123, -1e-7, 3.3333333333333335}));
}

// --- materials -------------------------------------------------------------------------------

TEST(ObjReaderTest, MaterialsMapOntoTheWhittedModel) {
  const std::string library =
      "newmtl red\nKd 0.8 0.1 0.1\nKs 0.2 0.2 0.2\nNs 64\n"
      "newmtl glass\nKd 0 0 0\nKs 0.1 0.1 0.1\nd 0.25\nNi 1.33\nillum 4\n"
      "newmtl chrome\nKd 0.05 0.05 0.05\nKs 0.9 0.8 0.7\nillum 3\n"
      "newmtl tinted\nTr 0.4\nKs 1 1 1\nillum 3\nNi 0\n";
  ObjModel model = ReadObj(
      "mtllib lib.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n"
      "o body\nusemtl red\nf 1 2 3\nusemtl chrome\nf 2 4 3\nf 1 2 4\n"
      "g lid\nf 1 2 3\nusemtl glass\nf 1 2 3\n",
      WithLibraries({{"lib.mtl", library}}));
  ASSERT_EQ(model.materials.size(), 4u);
  const Material& red = model.materials[0];
  EXPECT_EQ(red.name, "red");
  EXPECT_EQ(red.As<Phong>().diffuse, (Vec3{0.8, 0.1, 0.1}));
  EXPECT_EQ(red.As<Phong>().specular, (Vec3{0.2, 0.2, 0.2}));
  EXPECT_EQ(red.As<Phong>().shininess, 64);
  EXPECT_EQ(red.As<Phong>().reflectivity, 0);
  EXPECT_EQ(red.As<Phong>().transparency, 0);
  const Material& glass = model.materials[1];
  EXPECT_DOUBLE_EQ(glass.As<Phong>().transparency, 0.75);
  EXPECT_DOUBLE_EQ(glass.As<Phong>().indexOfRefraction, 1.33);
  EXPECT_EQ(glass.As<Phong>().reflectivity, 0);  // illum 4 is not a mirror
  const Material& chrome = model.materials[2];
  EXPECT_DOUBLE_EQ(chrome.As<Phong>().reflectivity, 0.9);
  const Material& tinted = model.materials[3];
  EXPECT_DOUBLE_EQ(tinted.As<Phong>().transparency, 0.4);    // Tr is 1 - d
  EXPECT_DOUBLE_EQ(tinted.As<Phong>().reflectivity, 0.6);    // capped: reflectivity + transparency <= 1
  EXPECT_EQ(tinted.As<Phong>().indexOfRefraction, 1);        // Ni 0 clamps to [1, 10]

  ASSERT_EQ(model.parts.size(), 4u);
  EXPECT_EQ(model.parts[0].name, "body");
  EXPECT_EQ(model.parts[0].material, 0);
  EXPECT_EQ(model.parts[1].material, 2);
  EXPECT_EQ(model.parts[1].triangleCount, 2u);
  EXPECT_EQ(model.parts[2].name, "lid");
  EXPECT_EQ(model.parts[2].material, 2);  // usemtl carries over a group change
  EXPECT_EQ(model.parts[3].material, 1);
  EXPECT_EQ(model.parts[3].firstTriangle, 4u);
}

TEST(ObjReaderTest, MaterialStatementsAreIgnoredWithoutALibraryReader) {
  ObjModel model = ReadObj("mtllib missing.mtl\nusemtl red\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", Options());
  EXPECT_TRUE(model.materials.empty());
  EXPECT_EQ(model.parts.at(0).material, -1);
}

TEST(ObjReaderTest, MaterialErrors) {
  const std::string geometry = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
  auto options = WithLibraries({{"lib.mtl", "newmtl red\nKd 0.8 0.1 0.1\n"}, {"bad.mtl", "newmtl neg\nKd 1 -1 1\n"}});
  EXPECT_TRUE(Fails("mtllib lib.mtl\n" + geometry + "usemtl blue\nf 1 2 3\n",
                    "model.obj line 5: usemtl \"blue\" names no material", options));
  EXPECT_TRUE(Fails("mtllib nope.mtl\n" + geometry, "no library nope.mtl at line 1", options));
  EXPECT_TRUE(Fails("mtllib bad.mtl\n" + geometry, "material \"neg\" of bad.mtl: Kd", options));
  EXPECT_TRUE(Fails(geometry + "usemtl\n", "line 4: usemtl without a name", options));
}

// --- errors ------------------------------------------------------------------------------------

TEST(ObjReaderTest, MalformedStatementsNameTheLine) {
  const std::string header = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
  EXPECT_TRUE(Fails(header + "f 1 2\n", "model.obj line 4: a face with 2 vertices"));
  EXPECT_TRUE(Fails(header + "vn 0 1\n", "line 4: a normal without exactly 3 coordinates"));
  EXPECT_TRUE(Fails(header + "vt\n", "line 4: a texture coordinate with 0 numbers"));
  EXPECT_TRUE(Fails(header + "vt 0 nan\n", "line 4: bad coordinate \"nan\""));
  EXPECT_TRUE(Fails(header + "f 1/ 2 3\n", "line 4: bad vertex reference \"1/\""));
  EXPECT_TRUE(Fails(header + "f 1/x 2 3\n", "line 4: texture coordinate reference \"x\""));
  EXPECT_TRUE(Fails(header + "vt 0 0\nf 1/1 2/2 3/1\n", "line 5: texture coordinate reference \"2\""));
  EXPECT_TRUE(Fails(header + "vn 0 0 1\nf 1//1 2//-2 3//1\n", "line 5: normal reference \"-2\""));
}

TEST(ObjReaderTest, TriangleBudgetCountsTriangulatedFaces) {
  ObjReadOptions options = Options();
  options.triangleBudget = 2;
  options.triangleLimit = 20;
  std::string quad = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n";
  EXPECT_NO_THROW(ReadObj(quad, options));
  EXPECT_TRUE(Fails(quad + "f 1 2 3\n", "line 6: the scene exceeds 20 triangles", options));
}

TEST(ObjReaderTest, InlineCommentsAndUnusedStatementsAreIgnored) {
  ObjModel model = ReadObj(
      "v 0 0 0 # origin\nv 1 0 0\nv 0 1 0\nl 1 2\np 1\nvp 0.5\ncstype bspline\nvw 0 0 1\nt x 0/0/0\n"
      "f 1 2 3 # one\n",
      Options());
  EXPECT_EQ(model.mesh.triangles.size(), 1u);
  EXPECT_EQ(ReadObj("\xEF\xBB\xBFv 0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\nf 1 2 3\r\n", Options()).mesh.vertices.size(), 3u);
}

}  // namespace
}  // namespace tcfarm
