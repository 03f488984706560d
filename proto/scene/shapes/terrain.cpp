// A terrain: {"type": "terrain", "origin", "size", "height", "cells", "seed"}, a
// heightfield mesh generated from those parameters (and written back as them).
//
// The mesh is procedural: fractal value noise over a regular grid.
//
// Every worker regenerates the mesh from the parameters, and a pixel traced on one
// machine is copied next to pixels traced on another, so the heights must be the same
// bits everywhere. The noise is therefore integer arithmetic; the few double operations
// are single correctly rounded IEEE operations (* and /, floor, and std::fma where a
// multiply meets an add, so no compiler may contract it differently on another target).
// TerrainTest.GoldenHeights pins the result; -ffast-math would break it.
#include <algorithm>
#include <cmath>
#include <cstdint>

#include "proto/scene/parse/scene_reader.h"
#include "proto/scene/scene.h"
#include "proto/scene/scene_write.h"
#include "proto/scene/shapes/shape_format.h"

namespace tcfarm {
namespace {

constexpr int kOctaves = 5;
// Lattice cells across the longer side of the terrain at the coarsest octave: a few hills.
constexpr int kBaseLatticeCells = 4;
constexpr int kFractionBits = 16;
constexpr int64_t kOne = int64_t{1} << kFractionBits;
constexpr int64_t kMaxLatticeValue = kOne - 1;
// Octave o weighs 2^(kOctaves-1-o): each finer octave adds half the detail of the last.
constexpr int64_t kWeightSum = (int64_t{1} << kOctaves) - 1;

// splitmix64's finaliser: cheap, and every input bit reaches every output bit.
uint64_t Mix(uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

// A pseudo-random height in [0, kMaxLatticeValue] at a lattice point of one octave.
int64_t LatticeValue(uint64_t seed, int octave, int64_t ix, int64_t iz) {
  uint64_t h = Mix(seed);
  h = Mix(h ^ static_cast<uint64_t>(octave));
  h = Mix(h ^ static_cast<uint64_t>(ix));
  h = Mix(h ^ static_cast<uint64_t>(iz));
  return static_cast<int64_t>(h >> (64 - kFractionBits));
}

// 3t^2 - 2t^3 in fixed point: flat at the lattice points, so the surface has no creases.
int64_t Smoothstep(int64_t t) { return t * t * (3 * kOne - 2 * t) / (kOne * kOne); }

int64_t Interpolate(int64_t a, int64_t b, int64_t t) { return a + (b - a) * t / kOne; }

struct LatticeCoordinate {
  int64_t cell;
  int64_t fraction;  // in [0, kOne)
};

LatticeCoordinate ToLattice(double position) {
  double cell = std::floor(position);
  return {static_cast<int64_t>(cell), static_cast<int64_t>((position - cell) * static_cast<double>(kOne))};
}

int64_t ValueNoise(uint64_t seed, int octave, double u, double v) {
  LatticeCoordinate x = ToLattice(u);
  LatticeCoordinate z = ToLattice(v);
  int64_t sx = Smoothstep(x.fraction);
  int64_t sz = Smoothstep(z.fraction);
  int64_t near = Interpolate(LatticeValue(seed, octave, x.cell, z.cell),
                             LatticeValue(seed, octave, x.cell + 1, z.cell), sx);
  int64_t far = Interpolate(LatticeValue(seed, octave, x.cell, z.cell + 1),
                            LatticeValue(seed, octave, x.cell + 1, z.cell + 1), sx);
  return Interpolate(near, far, sz);
}

// Fractal sum of octaves, in [0, 1]. u and v are the grid position as a fraction of the
// longer side, so the hills keep their shape whatever the terrain's size or resolution.
double Fbm(uint64_t seed, double u, double v) {
  int64_t sum = 0;
  for (int octave = 0; octave < kOctaves; ++octave) {
    double frequency = static_cast<double>(kBaseLatticeCells << octave);
    int64_t weight = int64_t{1} << (kOctaves - 1 - octave);
    sum += weight * ValueNoise(seed, octave, u * frequency, v * frequency);
  }
  return static_cast<double>(sum) / static_cast<double>(kWeightSum * kMaxLatticeValue);
}

uint32_t VertexIndex(const Shape::Terrain& terrain, int i, int k) {
  return static_cast<uint32_t>(k) * static_cast<uint32_t>(terrain.cellsX + 1) + static_cast<uint32_t>(i);
}

void AddVertices(const Shape::Terrain& terrain, TriangleMesh& mesh, const Checkpoint& checkpoint) {
  double longerSide = std::max(terrain.sizeX, terrain.sizeZ);
  double shareX = terrain.sizeX / longerSide;
  double shareZ = terrain.sizeZ / longerSide;
  for (int k = 0; k <= terrain.cellsZ; ++k) {
    if (checkpoint) checkpoint();
    double fractionZ = static_cast<double>(k) / static_cast<double>(terrain.cellsZ);
    for (int i = 0; i <= terrain.cellsX; ++i) {
      double fractionX = static_cast<double>(i) / static_cast<double>(terrain.cellsX);
      double noise = Fbm(terrain.seed, fractionX * shareX, fractionZ * shareZ);
      mesh.vertices.push_back(Vec3{std::fma(terrain.sizeX, fractionX, terrain.origin.x),
                                   std::fma(terrain.height, noise, terrain.origin.y),
                                   std::fma(terrain.sizeZ, fractionZ, terrain.origin.z)});
    }
  }
}

// Two triangles per cell, wound counter-clockwise seen from +y so geometric normals face up.
void AddTriangles(const Shape::Terrain& terrain, TriangleMesh& mesh) {
  for (int k = 0; k < terrain.cellsZ; ++k) {
    for (int i = 0; i < terrain.cellsX; ++i) {
      uint32_t v00 = VertexIndex(terrain, i, k);
      uint32_t v10 = VertexIndex(terrain, i + 1, k);
      uint32_t v01 = VertexIndex(terrain, i, k + 1);
      uint32_t v11 = VertexIndex(terrain, i + 1, k + 1);
      mesh.triangles.push_back({v00, v01, v10});
      mesh.triangles.push_back({v10, v01, v11});
    }
  }
}

}  // namespace

TriangleMesh GenerateTerrain(const Shape::Terrain& terrain, const Checkpoint& checkpoint) {
  TriangleMesh mesh;
  if (terrain.cellsX < 1 || terrain.cellsZ < 1) return mesh;
  mesh.vertices.reserve(static_cast<size_t>(terrain.cellsX + 1) * static_cast<size_t>(terrain.cellsZ + 1));
  mesh.triangles.reserve(2 * static_cast<size_t>(terrain.cellsX) * static_cast<size_t>(terrain.cellsZ));
  AddVertices(terrain, mesh, checkpoint);  // the noise: most of the time
  AddTriangles(terrain, mesh);
  return mesh;
}

namespace {

using namespace scene_parse;
using scene_write::Vec3Json;

void ReadTerrainCells(const Node& node, Shape::Terrain& terrain) {
  ExpectArray(node, 2, "[cells_x, cells_z], two integers in [1, 2000]");
  terrain.cellsX = ReadInt(node.Element(0), 1, kMaxTerrainCells);
  terrain.cellsZ = ReadInt(node.Element(1), 1, kMaxTerrainCells);
}

uint64_t ReadSeed(const Node& node) {
  const std::string expected = "an integer in [0, 18446744073709551615]";
  if (node.value.is_number_unsigned()) return node.value.get<uint64_t>();
  if (node.value.is_number_integer()) Fail(node.pointer, Show(node.value) + " is negative", expected);
  FailType(node, expected);
}

class TerrainFormatImpl final : public ShapeFormat {
 public:
  const char* Name() const override { return "terrain"; }

  void Read(SceneReader& reader, const Node& node, Shape& shape) const override {
    ExpectObject(node, SceneReader::ShapeFields({"origin", "size", "height", "cells", "seed"}), "a terrain");
    Shape::Terrain& terrain = shape.terrain;
    terrain.origin = ReadVec3(Required(node, "origin", kVec3Expected));
    const std::string sizeExpected = "[size_x, size_z], two positive finite numbers";
    Node size = Required(node, "size", sizeExpected);
    ExpectArray(size, 2, sizeExpected);
    terrain.sizeX = ReadPositive(size.Element(0), sizeExpected);
    terrain.sizeZ = ReadPositive(size.Element(1), sizeExpected);
    if (node.Has("height")) terrain.height = ReadNonNegative(node.Member("height"), "a non-negative finite height");
    if (node.Has("cells")) ReadTerrainCells(node.Member("cells"), terrain);
    if (node.Has("seed")) terrain.seed = ReadSeed(node.Member("seed"));
    reader.ChargeTriangles(2 * static_cast<size_t>(terrain.cellsX) * static_cast<size_t>(terrain.cellsZ),
                           node.Has("cells") ? node.Member("cells") : node);
  }

  void Complete(Shape& shape, const Checkpoint& checkpoint) const override {
    shape.mesh = GenerateTerrain(shape.terrain, checkpoint);
  }

  json Write(const Shape& shape) const override {
    const Shape::Terrain& t = shape.terrain;
    return json{{"origin", Vec3Json(t.origin)}, {"size", {t.sizeX, t.sizeZ}},      {"height", t.height},
                {"cells", {t.cellsX, t.cellsZ}}, {"seed", t.seed}};
  }

  // The parameters move with the generated mesh, so the scene writes back where it is.
  void Translate(Shape& shape, const Vec3& offset) const override {
    shape.terrain.origin = Moved(shape.terrain.origin, offset);
    for (Vec3& v : shape.mesh.vertices) v = Moved(v, offset);
  }

  bool PlaceStill(Shape& shape, const Affine& placement) const override {
    PlaceTrianglesStill(shape, placement);
    return true;
  }
};

}  // namespace

const ShapeFormat& TerrainFormat() {
  static const TerrainFormatImpl format;
  return format;
}

}  // namespace tcfarm
