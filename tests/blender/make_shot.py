"""Builds a small animated shot in Blender from nothing, exports it as glTF the way File >
Export > glTF 2.0 does, and renders its frame 1 with Cycles on the CPU (direct light only).
Runs inside Blender:

    blender -b --factory-startup --python tests/blender/make_shot.py -- OUT_DIR

OUT_DIR receives shot.gltf (+ shot.bin, uv_grid.png), cycles.exr (multilayer: the linear
Combined pass and the Object Index pass), cycles.png (view transform Standard) and
shot.json, which says what compare_shot.py needs: the frame, the frames per second, each
object's pass index, and the seconds the export and the render took.

The lights are Blender's own units: a Sun of 3 W/m^2 and a Point of 500 W. The exporter's
default lighting mode ('SPEC', "Standard") writes them as 683 * 3 = 2049 lx and
683 * 500 / (4 pi) = 27176 cd.
"""
import json
import math
import pathlib
import sys
import time

import bpy
from mathutils import Vector

SIZE = (320, 240)
FRAME = 1  # the frame Cycles renders: the first key of every animation
SAMPLES = 64
SUN_STRENGTH = 3.0  # W/m^2
POINT_POWER = 500.0  # W
# Object Index values: compare_shot.py masks each object's pixels with them.
PASS_INDEX = {"Floor": 1, "Suzanne": 2, "Ball": 3, "Panel": 4}
EMISSIVE = ("Panel",)


def principled(name, color, metallic=0.0, roughness=0.5):
    material = bpy.data.materials.new(name)
    material.use_nodes = True
    bsdf = material.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*color, 1)
    bsdf.inputs["Metallic"].default_value = metallic
    bsdf.inputs["Roughness"].default_value = roughness
    return material


def name_active(name, material):
    obj = bpy.context.active_object
    obj.name = name
    obj.pass_index = PASS_INDEX[name]
    obj.data.materials.append(material)
    return obj


def add_floor(out):
    """An 8 m plane whose base colour is Blender's generated UV grid, saved as a PNG so that
    the glTF refers to it as a file."""
    grid = bpy.data.images.new("uv_grid", 512, 512)
    grid.generated_type = "UV_GRID"
    grid.filepath_raw = str(out / "uv_grid.png")
    grid.file_format = "PNG"
    grid.save()
    material = principled("Floor", (1, 1, 1), roughness=0.9)
    nodes = material.node_tree.nodes
    texture = nodes.new("ShaderNodeTexImage")
    texture.image = grid
    material.node_tree.links.new(texture.outputs["Color"], nodes["Principled BSDF"].inputs["Base Color"])
    bpy.ops.mesh.primitive_plane_add(size=8)
    name_active("Floor", material)


def add_suzanne():
    """Gold metal, turning once about z over 48 frames."""
    bpy.ops.mesh.primitive_monkey_add(size=1.6, location=(-1.2, 0.3, 1.0))
    bpy.ops.object.shade_smooth()
    suzanne = name_active("Suzanne", principled("Gold", (1.0, 0.766, 0.336), metallic=1.0, roughness=0.3))
    for frame, turn in ((1, 0.0), (49, 2 * math.pi)):
        suzanne.rotation_euler = (0, 0, turn)
        suzanne.keyframe_insert("rotation_euler", frame=frame)


def add_ball():
    """A red dielectric ball bouncing: in the air at frame 1, on the floor at 13, up at 25."""
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.5, segments=48, ring_count=24, location=(1.3, -0.4, 1.6))
    bpy.ops.object.shade_smooth()
    ball = name_active("Ball", principled("Red", (0.8, 0.05, 0.04), roughness=0.4))
    for frame, height in ((1, 1.6), (13, 0.5), (25, 1.6)):
        ball.location.z = height
        ball.keyframe_insert("location", index=2, frame=frame)


def add_panel():
    """A small upright emissive panel (Emission Strength 4, so the exporter writes
    KHR_materials_emissive_strength)."""
    material = principled("Glow", (0.1, 0.1, 0.1))
    bsdf = material.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Emission"].default_value = (1.0, 0.45, 0.1, 1)
    bsdf.inputs["Emission Strength"].default_value = 4.0
    if hasattr(material.cycles, "sample_as_light"):
        material.cycles.sample_as_light = False  # a glowing sign, not a lamp: tcfarm's lights are punctual
    bpy.ops.mesh.primitive_plane_add(size=0.6, location=(0.2, 2.2, 0.9), rotation=(math.radians(90), 0, 0))
    name_active("Panel", material)


def add_light(name, kind, energy, location, rotation=(0, 0, 0)):
    light = bpy.data.lights.new(name, kind)
    light.energy = energy
    # Punctual, as glTF's lights are: no radius, no angular diameter.
    if kind == "POINT":
        light.shadow_soft_size = 0
    if kind == "SUN":
        light.angle = 0
    obj = bpy.data.objects.new(name, light)
    obj.location = location
    obj.rotation_euler = rotation
    bpy.context.scene.collection.objects.link(obj)


def add_camera(position, target):
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.location = position
    camera.rotation_euler = (Vector(target) - Vector(position)).to_track_quat("-Z", "Y").to_euler()
    bpy.context.scene.collection.objects.link(camera)
    bpy.context.scene.camera = camera


def build(out):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = SIZE  # the exporter's aspect ratio
    scene.render.resolution_percentage = 100
    scene.frame_start, scene.frame_end = 1, 49
    world = bpy.data.worlds.new("Black")
    world.color = (0, 0, 0)  # no light from the sky: only the two lamps light the shot
    scene.world = world
    add_floor(out)
    add_suzanne()
    add_ball()
    add_panel()
    add_light("Sun", "SUN", SUN_STRENGTH, (0, 0, 10), (math.radians(40), 0, math.radians(35)))
    add_light("Point", "POINT", POINT_POWER, (1.5, -2.0, 3.2))
    add_camera((7.0, -7.5, 4.8), (0, 0, 0.6))


def export(out):
    """File > Export > glTF 2.0 with its defaults, but for the Include panel's Cameras and
    Punctual Lights boxes, which are off by default."""
    bpy.ops.export_scene.gltf(filepath=str(out / "shot.gltf"), export_format="GLTF_SEPARATE",
                              export_cameras=True, export_lights=True)


def configure_cycles(scene):
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = SAMPLES
    scene.cycles.use_denoising = False  # Debian's Blender is built without OpenImageDenoise
    scene.cycles.max_bounces = 0  # direct light only, as a Whitted tracer's diffuse surfaces see it
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_layers[0].use_pass_object_index = True


def render(out):
    scene = bpy.context.scene
    configure_cycles(scene)
    scene.frame_set(FRAME)
    settings = scene.render.image_settings
    settings.file_format, settings.color_depth = "OPEN_EXR_MULTILAYER", "32"
    scene.render.filepath = str(out / "cycles.exr")
    bpy.ops.render.render(write_still=True)
    settings.file_format, settings.color_depth = "PNG", "8"
    bpy.data.images["Render Result"].save_render(str(out / "cycles.png"))


def main():
    out = pathlib.Path(sys.argv[sys.argv.index("--") + 1]).resolve()
    out.mkdir(parents=True, exist_ok=True)
    build(out)
    started = time.monotonic()
    export(out)
    exported = time.monotonic()
    render(out)
    rendered = time.monotonic()
    (out / "shot.json").write_text(json.dumps({
        "frame": FRAME, "fps": bpy.context.scene.render.fps, "size": list(SIZE), "samples": SAMPLES,
        "pass_index": PASS_INDEX, "emissive": list(EMISSIVE),
        "export_seconds": round(exported - started, 2), "render_seconds": round(rendered - exported, 2),
    }, indent=2) + "\n")


main()
