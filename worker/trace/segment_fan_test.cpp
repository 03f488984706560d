// The fan's shortlist may hold too much, never too little: every direction toward a
// sphere lies in the sphere's cone rectangle, and horizons searched frame by frame over a
// fan equal those each segment finds alone.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "proto/scene/scene.h"
#include "worker/trace/horizons.h"
#include "worker/trace/segment_fan.h"

namespace tcfarm {
namespace {

Vec3 RandomUnit(std::mt19937& random) {
  std::normal_distribution<double> normal;
  Vec3 v{normal(random), normal(random), normal(random)};
  const double length = std::sqrt(v.x * v.x + v.y * v.y + v.z * v.z);
  return {v.x / length, v.y / length, v.z / length};
}

TEST(SegmentFanTest, EveryDirectionTowardASphereLiesInItsConeOnItsFace) {
  std::mt19937 random(7);
  std::uniform_real_distribution<double> unit(0, 1);
  size_t checked = 0;
  for (int sphere = 0; sphere < 4000; ++sphere) {
    // Near and far, small and large, some holding the origin or touching a face's plane.
    const Vec3 toward = RandomUnit(random);
    const double distance = std::pow(10.0, 4 * unit(random) - 2);
    const double radius = distance * std::pow(10.0, 3 * unit(random) - 3) * (sphere % 17 == 0 ? 2 : 1);
    const Vec3 center{toward.x * distance, toward.y * distance, toward.z * distance};
    for (int point = 0; point < 50; ++point) {
      const Vec3 offset = RandomUnit(random);
      const double r = radius * std::cbrt(unit(random));
      const Vec3 p{center.x + offset.x * r, center.y + offset.y * r, center.z + offset.z * r};
      const CubeKey key = CubeKeyOf(float(p.x), float(p.y), float(p.z));
      const FaceRect rect = ConeOnFace(key.face, center, radius);
      ASSERT_FALSE(rect.Empty()) << "sphere " << sphere << " point " << point;
      EXPECT_TRUE(key.u >= rect.u0 && key.u <= rect.u1 && key.v >= rect.v0 && key.v <= rect.v1)
          << "sphere " << sphere << " point " << point << ": (" << key.u << ", " << key.v << ") on face "
          << key.face << " outside [" << rect.u0 << ", " << rect.u1 << "] x [" << rect.v0 << ", " << rect.v1 << "]";
      ++checked;
    }
  }
  EXPECT_EQ(checked, 200000u);
}

TEST(SegmentFanTest, ASphereWhollyBehindAFaceIsNotOnIt) {
  EXPECT_TRUE(ConeOnFace(/*+z*/ 4, {0, 0, -5}, 1).Empty());
  EXPECT_FALSE(ConeOnFace(/*-z*/ 5, {0, 0, -5}, 1).Empty());
  // Holding the origin: every face, whole.
  const FaceRect all = ConeOnFace(0, {0.1, 0, 0}, 1);
  EXPECT_EQ(all.u0, -1);
  EXPECT_EQ(all.u1, 1);
}

TEST(SegmentFanTest, OnlySegmentsWhoseLinesPassThePointAreTaken) {
  Scene scene = LoadSceneFile("tests/scenes/paper_b_twelve_spheres.json");
  HorizonOracle oracle(scene, 0, 10);
  const Vec3 light{5, 6, 9};
  FanCones cones(oracle, light, oracle.FanSlack(light));
  SegmentFan fan(&cones);
  // A shadow ray from a surface to the light: taken.
  const Float3 surface{-1, 2, -4};
  const Float3 toLight = Normalize(Float3{5, 6, 9} - surface);
  EXPECT_TRUE(fan.Add(0, {surface, toLight, Length(Float3{5, 6, 9} - surface)}));
  // The same ray started a tenth of a unit aside: its line misses the light.
  EXPECT_FALSE(fan.Add(1, {surface + Float3{0.1f, 0, 0}, toLight, 14}));
  // Running through the light and on beyond it: not one direction from the light.
  EXPECT_FALSE(fan.Add(2, {surface, toLight, 2 * Length(Float3{5, 6, 9} - surface)}));
}

// Segments from the camera's eye and toward the light of the paper's twelve spheres, in
// many directions and at many lengths: their horizons searched over fans equal
// FirstMeeting's, segment by segment.
TEST(SegmentFanTest, FanHorizonsEqualEachSegmentsOwnSearch) {
  Scene scene = LoadSceneFile("tests/scenes/paper_b_twelve_spheres.json");
  const int frame = 3, window = scene.render.LastFrame() - frame;
  HorizonOracle oracle(scene, frame, window);
  std::mt19937 random(11);
  std::uniform_real_distribution<float> unit(0, 1);
  for (const Vec3& point : {Vec3{0, 0, 10}, Vec3{5, 6, 9}}) {
    FanCones cones(oracle, point, oracle.FanSlack(point));
    SegmentFan fan(&cones);
    const Float3 p{float(point.x), float(point.y), float(point.z)};
    std::vector<int32_t> alone, fanned;
    for (uint32_t i = 0; i < 20000; ++i) {
      // Toward the spheres' reach mostly, anywhere else sometimes.
      const Float3 target{8 * unit(random) - 4, 6 * unit(random) - 3, 4 * unit(random) - 2};
      const Vec3 any = RandomUnit(random);
      const Float3 direction =
          i % 7 == 0 ? Float3{float(any.x), float(any.y), float(any.z)} : Normalize(target - p);
      const float length = i % 5 == 0 ? INFINITY : 30 * unit(random);
      RaySegment segment{p, direction, length};
      if (i % 2 == 1) {  // toward the point, ending at it, as a shadow ray does
        segment.origin = p + direction * length;
        if (!std::isfinite(length)) segment.origin = p + direction * 20.0f;
        segment.direction = -direction;
        segment.length = Length(p - segment.origin);
      }
      ASSERT_TRUE(fan.Add(static_cast<uint32_t>(alone.size()), segment)) << "segment " << i;
      alone.push_back(oracle.FirstMeeting(segment));
    }
    fan.Index();
    fanned.assign(alone.size(), oracle.Unbounded());
    oracle.FanFirstMeetings(fan, fanned.data());
    size_t met = 0;
    for (size_t i = 0; i < alone.size(); ++i) {
      ASSERT_EQ(fanned[i], alone[i]) << "segment " << i;
      met += alone[i] < oracle.Unbounded();
    }
    EXPECT_GT(met, alone.size() / 4) << "the spheres should meet some segments";
  }
}

}  // namespace
}  // namespace tcfarm
