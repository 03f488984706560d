"""Measures what Cycles' lamps emit, in the units tcfarm's scene uses: a point lamp of P
watts as radiant intensity (W/sr) and a sun of strength S as irradiance (W/m^2). Runs
inside Blender:

    blender -b --factory-startup --python tests/blender/cycles_light_units.py -- OUT_DIR

A white Lambertian plane (Diffuse BSDF, colour 1) seen from straight above by an
orthographic camera, lit from straight above by one lamp at a time; its radiance L under
the lamp gives the irradiance E = pi L. For the point lamp at height h, the intensity is
E h^2. Prints one JSON object: each lamp's setting, the pixel value and the ratio to the
expected P / (4 pi) and S (1 when Blender's watts are radiometric as they say).
"""
import json
import math
import pathlib
import sys

import bpy
import numpy as np

SIZE = 64
HEIGHT = 2.0  # metres from the point lamp to the plane
POINT_POWER = 1000.0  # W
SUN_STRENGTH = 3.0  # W/m^2


def white_plane():
    bpy.ops.mesh.primitive_plane_add(size=20)
    material = bpy.data.materials.new("White")
    material.use_nodes = True
    nodes, links = material.node_tree.nodes, material.node_tree.links
    nodes.clear()
    diffuse = nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (1, 1, 1, 1)
    links.new(diffuse.outputs[0], nodes.new("ShaderNodeOutputMaterial").inputs[0])
    bpy.context.active_object.data.materials.append(material)


def set_up():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = 16
    scene.cycles.use_denoising = False
    scene.cycles.max_bounces = 0
    scene.render.resolution_x = scene.render.resolution_y = SIZE
    world = bpy.data.worlds.new("Black")
    world.color = (0, 0, 0)
    scene.world = world
    white_plane()
    camera = bpy.data.cameras.new("Camera")
    camera.type, camera.ortho_scale = "ORTHO", 1.0  # 1 m across
    obj = bpy.data.objects.new("Camera", camera)
    obj.location = (0, 0, 5)
    scene.collection.objects.link(obj)
    scene.camera = obj


def radiance_under(kind, energy, out):
    """The plane's mean radiance over the middle 2 x 2 pixels (3 cm across: the point lamp's
    cos^3 falloff there is under 1e-4), lit by one lamp above it."""
    scene = bpy.context.scene
    for old in [obj for obj in scene.objects if obj.type == "LIGHT"]:
        bpy.data.objects.remove(old)
    light = bpy.data.lights.new(kind, kind)
    light.energy = energy
    if kind == "POINT":
        light.shadow_soft_size = 0
    else:
        light.angle = 0
    obj = bpy.data.objects.new(kind, light)
    obj.location = (0, 0, HEIGHT)
    scene.collection.objects.link(obj)
    scene.render.image_settings.file_format, scene.render.image_settings.color_depth = "OPEN_EXR", "32"
    scene.render.filepath = str(out / f"{kind.lower()}.exr")
    bpy.ops.render.render(write_still=True)
    pixels = np.array(bpy.data.images.load(scene.render.filepath).pixels[:]).reshape(SIZE, SIZE, 4)
    middle = slice(SIZE // 2 - 1, SIZE // 2 + 1)
    return float(pixels[middle, middle, 0].mean())


def main():
    out = pathlib.Path(sys.argv[sys.argv.index("--") + 1]).resolve()
    out.mkdir(parents=True, exist_ok=True)
    set_up()
    point = radiance_under("POINT", POINT_POWER, out)
    sun = radiance_under("SUN", SUN_STRENGTH, out)
    intensity = math.pi * point * HEIGHT ** 2
    print("cycles_light_units " + json.dumps({
        "point": {"watts": POINT_POWER, "radiance": point, "intensity_w_per_sr": intensity,
                  "ratio_to_p_over_4pi": intensity / (POINT_POWER / (4 * math.pi))},
        "sun": {"strength": SUN_STRENGTH, "radiance": sun, "irradiance": math.pi * sun,
                "ratio_to_strength": math.pi * sun / SUN_STRENGTH},
    }))


main()
