// Whether a ray may meet two surfaces of the scene at exactly the same distance over an
// area rather than along a line: only then does the scene carry the tie rule
// (closest_hit.h), on every shape.
//
// Settling ties costs: Embree calls the rule at every candidate hit of a shape that has
// it (about a third more tracing time on the paper's scenes). Surfaces in general position
// meet along curves, where two distances equal to the last bit are freak events; surfaces
// that coincide over an area (a quad lying on a floor, a decal, a face doubled in a mesh,
// two equal spheres in one place) tie at every pixel that sees the overlap. So the rule
// goes on when some surface may coincide with another, judged conservatively:
//   - a still planar primitive (quad, mesh or terrain triangle) whose plane another still
//     planar primitive shares, within a tolerance far above float rounding;
//   - every planar shape, when any planar shape moves (a moving plane may come to lie in
//     any other at some frame);
//   - spheres of one radius when one of them moves or both share a centre; every sphere
//     when a sphere scales.
// A mesh too large to hash cheaply turns the rule on without looking. The rule is all or
// nothing: it keeps a ray's tfar a little beyond its closest hit, which a shape without
// the rule would take for a closer hit.
#pragma once

#include "proto/scene/scene.h"

namespace tcfarm {

// Whether any two surfaces of the scene may tie over an area.
bool SceneMayTie(const Scene& scene);

// Its sphere part: whether two spheres may coincide (equal radii where one moves or both
// share a centre; any two once a sphere scales). Radii and centres are compared through a
// sort and sweep, never pair by pair, so it costs O(n log n) in the spheres.
bool SpheresMayMeet(const Scene& scene);

}  // namespace tcfarm
