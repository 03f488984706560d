#!/usr/bin/env python3
"""Writes the paper's three test animations (section 5) as tcfarm scenes.

  a) one sphere moving toward the viewer and diagonally right and down,
     a background polygon, one light (paper: 95 % frame-to-frame coherence);
  b) a dozen spheres of varying colour and size on random trajectories from a loose
     cluster near the centre, a background polygon, one light (paper: 86 %);
  c) a camera flying over a 20,000-polygon terrain with a background polygon (paper: 82 %).

60 frames at 640x480 each. The scenes are committed; rerun this after changing it.
"""
import json
import pathlib
import random

HERE = pathlib.Path(__file__).resolve().parent
RENDER = {"width": 640, "height": 480, "frames": {"start": 0, "count": 60},
          "samples_per_pixel": 1, "max_depth": 3}


def linear(start, velocity):
    """Polynomial motion start + velocity * frame, per axis."""
    return {"polynomial": [[s, v] for s, v in zip(start, velocity)]}


def backdrop():
    return {"type": "quad", "name": "backdrop", "corner": [-12, -9, -4],
            "edge_u": [24, 0, 0], "edge_v": [0, 18, 0], "material": "backdrop"}


def one_sphere():
    return {
        "camera": {"position": [0, 0, 10], "look_at": [0, 0, 0], "fov_degrees": 45},
        "lights": [{"type": "point", "position": [5, 6, 9], "intensity": [190, 190, 190]}],
        "materials": {
            "backdrop": {"diffuse": [0.75, 0.75, 0.7]},
            "ball": {"diffuse": [0.8, 0.25, 0.2], "specular": [0.4, 0.4, 0.4], "shininess": 40},
        },
        "shapes": [
            backdrop(),
            {"type": "sphere", "name": "ball", "center": [0, 0, 0], "radius": 1.0,
             "material": "ball", "motion": linear([-1.6, 1.3, -1.5], [0.03, -0.025, 0.05])},
        ],
        "background": [0.05, 0.05, 0.08],
        "render": RENDER,
    }


def twelve_spheres():
    rng = random.Random(1987)
    materials = {"backdrop": {"diffuse": [0.75, 0.75, 0.7]}}
    shapes = [backdrop()]
    for i in range(12):
        name = f"ball{i:02d}"
        materials[name] = {"diffuse": [round(rng.uniform(0.15, 0.9), 3) for _ in range(3)],
                           "specular": [0.35, 0.35, 0.35], "shininess": 30}
        start = [round(rng.uniform(-1.5, 1.5), 3), round(rng.uniform(-1.2, 1.2), 3),
                 round(rng.uniform(-2.0, 0.5), 3)]
        velocity = [round(rng.uniform(-0.11, 0.11), 4) for _ in range(2)] + [
            round(rng.uniform(-0.04, 0.05), 4)]
        shapes.append({"type": "sphere", "name": name, "center": [0, 0, 0],
                       "radius": round(rng.uniform(0.35, 0.8), 3), "material": name,
                       "motion": linear(start, velocity)})
    return {
        "camera": {"position": [0, 0, 10], "look_at": [0, 0, 0], "fov_degrees": 45},
        "lights": [{"type": "point", "position": [5, 6, 9], "intensity": [190, 190, 190]}],
        "materials": materials,
        "shapes": shapes,
        "background": [0.05, 0.05, 0.08],
        "render": RENDER,
    }


def terrain_flyover():
    # A sun (directional light) lights the flat-shaded terrain and the sky polygon
    # uniformly, as in the paper's flat-shaded 1988 renderer.
    return {
        "camera": {"position": linear([0, 22, 45], [0.03, 0, -0.3]),
                   "look_at": linear([0, 12, -10], [0.03, 0, -0.3]), "fov_degrees": 50},
        "lights": [{"type": "directional", "direction": [-0.4, -1.0, -0.5],
                    "intensity": [1.1, 1.05, 0.95]}],
        "materials": {
            "ground": {"diffuse": [0.35, 0.55, 0.25]},
            "sky": {"diffuse": [0.45, 0.6, 0.9]},
        },
        "shapes": [
            {"type": "terrain", "name": "terrain", "origin": [-50, 0, -50], "size": [100, 100],
             "height": 7, "cells": [100, 100], "seed": 11, "material": "ground"},
            # Tilted toward the sun so the sun lights it.
            {"type": "quad", "name": "sky", "corner": [-300, -20, -60], "edge_u": [600, 0, 0],
             "edge_v": [0, 200, 40], "material": "sky"},
        ],
        "background": [0.0, 0.0, 0.0],
        "render": RENDER,
    }


def main():
    for name, scene in [("paper_a_one_sphere", one_sphere()),
                        ("paper_b_twelve_spheres", twelve_spheres()),
                        ("paper_c_terrain_flyover", terrain_flyover())]:
        path = HERE / f"{name}.json"
        path.write_text(json.dumps(scene, indent=1) + "\n")
        print(path)


if __name__ == "__main__":
    main()
