"""The reference harness reads the Khronos glTF Sample Renderer's values right: a flat
panel under one directional light, rendered by khronos_render.py, matches the glTF 2.0
specification's BRDF (Appendix B) evaluated here per pixel, with light intensities taken as
they are (irradiance = intensity x colour), exposure 1 and no gamma or tone curve left in
the values."""
import math
import pathlib
import sys

import numpy as np
import pytest

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from make_assets import Asset, look_at, panel  # noqa: E402

if not (HERE / "node_modules").is_dir():
    pytest.fail("tests/reference/node_modules is missing: run scripts/bootstrap")

from khronos_render import KhronosRenderer  # noqa: E402

WIDTH, HEIGHT, YFOV = 64, 48, 0.8
EYE = np.array([0.0, 0.0, 3.0])
TILT = math.radians(30)  # the panel turned about x, its normal tipped up
BASE = np.array([0.8, 0.5, 0.3])
LIGHT_TOWARD = np.array([0.3, -0.5, -1.0]) / np.linalg.norm([0.3, -0.5, -1.0])
LIGHT = np.array([1.0, 0.9, 0.8]) * 2.0  # colour x intensity (lux)


def lambert_panel(path):
    g = Asset("lambert_panel")
    material = g.pbr("lambert", tuple(BASE), metallic=0.0, roughness=1.0)
    positions, normals, uvs, indices, _ = panel(2.0, 2.0)
    g.add_mesh([g.primitive(positions, normals, indices, material, uv0=uvs)],
               rotation=[-math.sin(TILT / 2), 0, 0, math.cos(TILT / 2)])
    camera = g._add("cameras", {"type": "perspective", "perspective": {"yfov": YFOV, "znear": 0.05}})
    g.node(camera=camera, translation=list(EYE))
    g.punctual("directional", 2.0, (1.0, 0.9, 0.8), toward=list(LIGHT_TOWARD))
    return g.write_to(path)


def specification_brdf(n, l, v, base, metallic, roughness):
    """glTF 2.0 Appendix B: mix(fresnel_mix(ior 1.5, diffuse, specular), conductor_fresnel(
    base, specular), metallic), specular = V x D of the GGX distribution, alpha = roughness^2."""
    h = (l + v) / np.linalg.norm(l + v)
    n_l, n_v, n_h, v_h = (float(np.dot(a, b)) for a, b in ((n, l), (n, v), (n, h), (v, h)))
    alpha2 = roughness ** 4
    visibility = 1.0 / ((abs(n_l) + math.sqrt(alpha2 + (1 - alpha2) * n_l * n_l)) *
                        (abs(n_v) + math.sqrt(alpha2 + (1 - alpha2) * n_v * n_v)))
    distribution = alpha2 / (math.pi * (n_h * n_h * (alpha2 - 1) + 1) ** 2)
    specular = visibility * distribution
    schlick = (1 - abs(v_h)) ** 5
    dielectric_f = 0.04 + 0.96 * schlick
    dielectric = (1 - dielectric_f) * base / math.pi + dielectric_f * specular
    metal = (base + (1 - base) * schlick) * specular
    return (1 - metallic) * dielectric + metallic * metal


def expected_image():
    """Radiance per pixel (NaN off the panel): BRDF x light x cos, seen through each pixel's
    centre."""
    normal = np.array([0.0, math.sin(TILT), math.cos(TILT)])
    up_in_plane = np.array([0.0, math.cos(TILT), -math.sin(TILT)])
    to_light = -LIGHT_TOWARD
    image = np.full((HEIGHT, WIDTH, 3), np.nan)
    half = math.tan(YFOV / 2)
    for y in range(HEIGHT):
        for x in range(WIDTH):
            ray = np.array([(2 * (x + 0.5) / WIDTH - 1) * half * WIDTH / HEIGHT,
                            (1 - 2 * (y + 0.5) / HEIGHT) * half, -1.0])
            ray /= np.linalg.norm(ray)
            point = EYE + ray * (-np.dot(normal, EYE) / np.dot(normal, ray))
            if abs(point[0]) > 1 or abs(np.dot(point, up_in_plane)) > 1:
                continue
            cosine = max(float(np.dot(normal, to_light)), 0.0)
            image[y, x] = specification_brdf(normal, to_light, -ray, BASE, 0.0, 1.0) * LIGHT * cosine
    return image


def test_a_lambert_panel_matches_the_specification_brdf(tmp_path):
    assert look_at([0, 0, 3], [0, 0, 0]) == pytest.approx([0, 0, 0, 1])
    asset = lambert_panel(tmp_path)
    with KhronosRenderer(tmp_path / "chromium") as renderer:
        pixels, alpha = renderer.render_rgba(asset, WIDTH, HEIGHT)
    expected = expected_image()
    on_panel = ~np.isnan(expected[..., 0])
    # Away from the panel's edges, where a pixel centre may fall on either side.
    inner = on_panel & np.roll(on_panel, 1, 0) & np.roll(on_panel, -1, 0) & \
        np.roll(on_panel, 1, 1) & np.roll(on_panel, -1, 1)
    assert inner.sum() > 0.3 * WIDTH * HEIGHT, asset
    assert (alpha[inner] == 1).all() and (alpha[~on_panel & np.roll(~on_panel, 1, 0)] == 0).all()
    relative = np.abs(pixels[inner] - expected[inner]) / expected[inner]
    print(f"Khronos vs Appendix B: median {np.median(relative):.3%}, worst {relative.max():.3%}, "
          f"centre pixel {pixels[HEIGHT // 2, WIDTH // 2]} vs {expected[HEIGHT // 2, WIDTH // 2]}")
    assert relative.max() < 0.01
