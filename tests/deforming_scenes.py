"""Scenes with deforming meshes, written as tcfarm scene JSON (dicts): a skinned arm that
bends before a still wall, and a morphing blob that casts a shadow on the floor."""
import math


def _quaternion_about_z(degrees):
    half = math.radians(degrees) / 2
    return [0, 0, math.sin(half), math.cos(half)]


def skinned_arm(x0=-1.0, segments=4, bend_degrees=60, frames=12, pause=(4, 7)):
    """A square bar along x from x0, bound to two joints: the first holds its left half,
    the second (the elbow, at x0 + 1) bends the right half about z, holding still over
    `pause`. Rings of 4 vertices; the elbow ring blends both joints."""
    vertices, joints, weights, triangles = [], [], [], []
    rings = segments + 1
    for ring in range(rings):
        x = x0 + 2.0 * ring / segments
        second = 0.0 if x < x0 + 1 - 1e-9 else (0.5 if abs(x - (x0 + 1)) < 1e-9 else 1.0)
        for y, z in ((0.8, -0.2), (0.8, 0.2), (1.2, 0.2), (1.2, -0.2)):
            vertices.append([x, y, z])
            joints.append([0, 1, 0, 0])
            weights.append([1 - second, second, 0, 0])
    for ring in range(segments):
        for corner in range(4):
            a, b = 4 * ring + corner, 4 * ring + (corner + 1) % 4
            c, d = b + 4, a + 4
            triangles += [[a, b, c], [a, c, d]]
    last = 4 * segments
    triangles += [[0, 2, 1], [0, 3, 2], [last, last + 1, last + 2], [last, last + 2, last + 3]]
    held = bend_degrees * pause[0] / (frames - 1)
    keys = [{"frame": 0, "value": _quaternion_about_z(0)},
            {"frame": pause[0], "value": _quaternion_about_z(held)},
            {"frame": pause[1], "value": _quaternion_about_z(held)},
            {"frame": frames - 1, "value": _quaternion_about_z(bend_degrees)}]
    elbow = x0 + 1
    return {
        "type": "mesh", "name": "arm", "material": "skin", "vertices": vertices, "triangles": triangles,
        "skin": {
            "joints": [[0, 0, 0], {"translation": [elbow, 1, 0], "rotation": {"keyframes": keys}}],
            "inverse_bind_matrices": [[1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0],
                                      [1, 0, 0, -elbow, 0, 1, 0, -1, 0, 0, 1, 0]],
            "vertex_joints": joints, "vertex_weights": weights,
        },
    }


def morphing_blob(center=(-2.0, 1.0, 0.5), radius=0.6):
    """A smooth octahedron whose top rises and sides swell by one morph target, its weight
    on a cubic spline."""
    cx, cy, cz = center
    r = radius
    return {
        "type": "mesh", "name": "blob", "material": "blob",
        "vertices": [[cx, cy + r, cz], [cx + r, cy, cz], [cx, cy, cz + r], [cx - r, cy, cz],
                     [cx, cy, cz - r], [cx, cy - r, cz]],
        "normals": [[0, 1, 0], [1, 0, 0], [0, 0, 1], [-1, 0, 0], [0, 0, -1], [0, -1, 0]],
        "triangles": [[0, 2, 1], [0, 3, 2], [0, 4, 3], [0, 1, 4], [5, 1, 2], [5, 2, 3], [5, 3, 4],
                      [5, 4, 1]],
        "morph": {
            "targets": [{"positions": [[0, 0.5, 0], [0.2, 0, 0], [0, 0, 0.2], [-0.2, 0, 0], [0, 0, -0.2],
                                       [0, 0, 0]],
                         "normals": [[0, 0, 0], [0, 0.3, 0], [0, 0.3, 0], [0, 0.3, 0], [0, 0.3, 0],
                                     [0, 0, 0]]}],
            "weights": {"interpolation": "cubicspline", "keyframes": [
                {"frame": 0, "value": [0], "in_tangent": [0], "out_tangent": [0.1]},
                {"frame": 6, "value": [1], "in_tangent": [0], "out_tangent": [0]},
                {"frame": 11, "value": [0.2], "in_tangent": [-0.1], "out_tangent": [0]}]},
        },
    }


def deforming_set(width=96, height=72, frames=12, mirror=False):
    """The arm before a still wall (or a mirror) and the blob on the floor, one point light."""
    backdrop = {"type": "quad", "corner": [-6, 0, -3], "edge_u": [12, 0, 0],
                "edge_v": [0, 6, 0.5] if mirror else [0, 6, 0], "material": "mirror" if mirror else "wall"}
    return {
        "camera": {"position": [0, 2, 8], "look_at": [0, 1, 0]},
        "lights": [{"type": "point", "position": [4, 6, 3], "intensity": [30, 30, 30]}],
        "materials": {"skin": {"diffuse": [0.8, 0.5, 0.4], "specular": [0.2, 0.2, 0.2], "shininess": 20},
                      "blob": {"diffuse": [0.2, 0.4, 0.9]}, "wall": {"diffuse": [0.7, 0.7, 0.65]},
                      "floor": {"diffuse": [0.6, 0.6, 0.6]},
                      "mirror": {"diffuse": [0.05, 0.05, 0.05], "reflectivity": 0.9}},
        "shapes": [{"type": "quad", "corner": [-20, 0, -20], "edge_u": [0, 0, 40], "edge_v": [40, 0, 0],
                    "material": "floor"},
                   backdrop, skinned_arm(x0=0.5 if mirror else -1.0, frames=frames), morphing_blob()],
        "background": [0.1, 0.1, 0.2],
        "render": {"width": width, "height": height, "frames": {"start": 0, "count": frames}},
    }
