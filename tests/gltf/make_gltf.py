"""Writes small glTF 2.0 files for the importer's tests: plain JSON, buffers as base64 data
URIs (or one GLB), no dependencies beyond the standard library.

    python3 tests/gltf/make_gltf.py OUT_DIR     # writes every example scene there

Each example is a function returning a Gltf; tests call them and pick what they need.
"""
import base64
import json
import math
import pathlib
import struct
import sys
import zlib

FLOAT, UNSIGNED_BYTE, UNSIGNED_SHORT, UNSIGNED_INT = 5126, 5121, 5123, 5125
TRIANGLES, TRIANGLE_STRIP, TRIANGLE_FAN = 4, 5, 6
_FORMATS = {FLOAT: "f", UNSIGNED_BYTE: "B", UNSIGNED_SHORT: "H", UNSIGNED_INT: "I"}
_COMPONENTS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}


def png_bytes(rows):
    """An 8-bit RGB (or RGBA) PNG of rows of (r, g, b[, a]) codes, top row first."""
    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    height, width = len(rows), len(rows[0])
    raw = b"".join(b"\0" + bytes(c for texel in row for c in texel) for row in rows)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 6 if len(rows[0][0]) == 4 else 2, 0, 0, 0)) +
            chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


def checker(size, a, b):
    """size x size texels alternating colours a and b."""
    return [[a if (x + y) % 2 == 0 else b for x in range(size)] for y in range(size)]


def axis_angle(axis, degrees):
    """glTF's quaternion [x, y, z, w] of a turn about axis."""
    length = math.sqrt(sum(a * a for a in axis))
    half = math.radians(degrees) / 2
    return [a / length * math.sin(half) for a in axis] + [math.cos(half)]


class Gltf:
    def __init__(self):
        self.doc = {"asset": {"version": "2.0", "generator": "tcfarm tests/gltf/make_gltf.py"},
                    "scene": 0, "scenes": [{"nodes": []}], "nodes": [], "meshes": [],
                    "accessors": [], "bufferViews": [], "buffers": []}
        self.buffer = bytearray()

    def _add(self, name, item):
        self.doc.setdefault(name, []).append(item)
        return len(self.doc[name]) - 1

    def accessor(self, values, type_, component=FLOAT, normalized=False, target=None, bounds=False):
        """A tightly packed accessor of flat `values`; returns its index. target: 34962 for
        vertex attributes, 34963 for indices; bounds: write min and max (positions and
        key times need them)."""
        while len(self.buffer) % 4:
            self.buffer.append(0)
        data = struct.pack("<%d%s" % (len(values), _FORMATS[component]), *values)
        view = {"buffer": 0, "byteOffset": len(self.buffer), "byteLength": len(data)}
        if target:
            view["target"] = target
        view = self._add("bufferViews", view)
        self.buffer += data
        accessor = {"bufferView": view, "componentType": component, "type": type_,
                    "count": len(values) // _COMPONENTS[type_]}
        if normalized:
            accessor["normalized"] = True
        if bounds:  # as stored: rounded to float
            stored = struct.unpack("<%d%s" % (len(values), _FORMATS[component]), data)
            n = _COMPONENTS[type_]
            accessor["min"] = [min(stored[i::n]) for i in range(n)]
            accessor["max"] = [max(stored[i::n]) for i in range(n)]
        return self._add("accessors", accessor)

    def texture(self, png, how="data", uri=None, wrap=None, mag_filter=None, min_filter=None):
        """A texture of PNG bytes stored `how`: "data" (a data URI), "view" (a buffer view,
        as a GLB holds images) or "file" (uri, a file the caller writes beside the glTF);
        wrap: (wrapS, wrapT) codes; mag_filter: 9728 nearest, 9729 linear; min_filter: those,
        or 9984-9987 (the mipmapped ones)."""
        if how == "data":
            image = {"uri": "data:image/png;base64," + base64.b64encode(png).decode()}
        elif how == "view":
            while len(self.buffer) % 4:
                self.buffer.append(0)
            view = self._add("bufferViews", {"buffer": 0, "byteOffset": len(self.buffer), "byteLength": len(png)})
            self.buffer += png
            image = {"bufferView": view, "mimeType": "image/png"}
        else:
            image = {"uri": uri}
        texture = {"source": self._add("images", image)}
        if wrap or mag_filter or min_filter:
            sampler = {}
            if wrap:
                sampler["wrapS"], sampler["wrapT"] = wrap
            if mag_filter:
                sampler["magFilter"] = mag_filter
            if min_filter:
                sampler["minFilter"] = min_filter
            texture["sampler"] = self._add("samplers", sampler)
        return self._add("textures", texture)

    def material(self, name, base_color, metallic=0.0, roughness=1.0, transmission=None, ior=None, texture=None):
        material = {"name": name, "pbrMetallicRoughness": {
            "baseColorFactor": list(base_color) + [1.0], "metallicFactor": metallic,
            "roughnessFactor": roughness}}
        if texture is not None:
            material["pbrMetallicRoughness"]["baseColorTexture"] = {"index": texture}
        if transmission is not None or ior is not None:
            material["extensions"] = {}
        if transmission is not None:
            material["extensions"]["KHR_materials_transmission"] = {"transmissionFactor": transmission}
            self._use("KHR_materials_transmission")
        if ior is not None:
            material["extensions"]["KHR_materials_ior"] = {"ior": ior}
            self._use("KHR_materials_ior")
        return self._add("materials", material)

    def mesh(self, primitives, name=None, weights=None):
        """primitives: dicts of positions (flat), indices, mode, material, normals, uvs,
        colors (flat RGBA in [0, 1], COLOR_0), joints and weights (flat, 4 per vertex: JOINTS_0 as unsigned bytes, WEIGHTS_0 as
        floats) and targets (morph targets: dicts of positions and normals, flat deltas);
        weights: the mesh's default morph target weights."""
        out = []
        for p in primitives:
            primitive = {"attributes": {"POSITION": self.accessor(p["positions"], "VEC3", target=34962,
                                                                  bounds=True)}}
            if p.get("normals"):
                primitive["attributes"]["NORMAL"] = self.accessor(p["normals"], "VEC3", target=34962)
            if p.get("uvs"):
                primitive["attributes"]["TEXCOORD_0"] = self.accessor(
                    [round(u * 65535) for u in p["uvs"]], "VEC2", UNSIGNED_SHORT, normalized=True,
                    target=34962)
            if p.get("colors"):  # RGBA, normalized unsigned bytes (the alpha is not used)
                primitive["attributes"]["COLOR_0"] = self.accessor(
                    [round(c * 255) for c in p["colors"]], "VEC4", UNSIGNED_BYTE, normalized=True, target=34962)
            if p.get("joints"):
                primitive["attributes"]["JOINTS_0"] = self.accessor(p["joints"], "VEC4", UNSIGNED_BYTE, target=34962)
                primitive["attributes"]["WEIGHTS_0"] = self.accessor(p["weights"], "VEC4", target=34962)
            if p.get("targets"):
                primitive["targets"] = [
                    {**{"POSITION": self.accessor(t["positions"], "VEC3", target=34962, bounds=True)},
                     **({"NORMAL": self.accessor(t["normals"], "VEC3", target=34962)} if t.get("normals") else {})}
                    for t in p["targets"]]
            if p.get("indices"):
                # 16-bit indices where they fit (65,535 is primitive restart), else 32-bit.
                component = UNSIGNED_SHORT if max(p["indices"]) < 0xFFFF else UNSIGNED_INT
                primitive["indices"] = self.accessor(p["indices"], "SCALAR", component, target=34963)
            if p.get("mode", TRIANGLES) != TRIANGLES:
                primitive["mode"] = p["mode"]
            if p.get("material") is not None:
                primitive["material"] = p["material"]
            out.append(primitive)
        mesh = {"primitives": out}
        if name:
            mesh["name"] = name
        if weights:
            mesh["weights"] = list(weights)
        return self._add("meshes", mesh)

    def skin(self, joints, inverse_binds):
        """A skin of joint nodes, each with its inverse bind matrix (16 numbers, column-major)."""
        return self._add("skins", {"joints": list(joints), "inverseBindMatrices": self.accessor(
            [v for matrix in inverse_binds for v in matrix], "MAT4")})

    def node(self, parent=None, **properties):
        """A node (name, mesh, camera, translation, rotation, scale, matrix, light); a root
        of the scene unless it has a parent."""
        light = properties.pop("light", None)
        if light is not None:
            properties["extensions"] = {"KHR_lights_punctual": {"light": light}}
        index = self._add("nodes", properties)
        if parent is None:
            self.doc["scenes"][0]["nodes"].append(index)
        else:
            self.doc["nodes"][parent].setdefault("children", []).append(index)
        return index

    def camera(self, yfov, name=None):
        camera = {"type": "perspective", "perspective": {"yfov": yfov, "znear": 0.05}}
        if name:
            camera["name"] = name
        return self._add("cameras", camera)

    def light(self, type_, intensity, color=(1.0, 1.0, 1.0)):
        self._use("KHR_lights_punctual")
        lights = self.doc.setdefault("extensions", {}).setdefault(
            "KHR_lights_punctual", {"lights": []})["lights"]
        lights.append({"type": type_, "intensity": intensity, "color": list(color)})
        return len(lights) - 1

    def animate(self, node, path, times, values, interpolation="LINEAR", animation=0, name=None):
        """A channel of animation `animation`; values flat (for CUBICSPLINE: in-tangent,
        value, out-tangent per key, tangents per second; for weights, one value per morph
        target for each)."""
        animations = self.doc.setdefault("animations", [])
        while len(animations) <= animation:
            animations.append({"channels": [], "samplers": []})
        if name:
            animations[animation]["name"] = name
        samplers = animations[animation]["samplers"]
        type_ = {"rotation": "VEC4", "weights": "SCALAR"}.get(path, "VEC3")
        samplers.append({"input": self.accessor(times, "SCALAR", bounds=True),
                         "output": self.accessor(values, type_), "interpolation": interpolation})
        animations[animation]["channels"].append(
            {"sampler": len(samplers) - 1, "target": {"node": node, "path": path}})

    def _use(self, extension):
        used = self.doc.setdefault("extensionsUsed", [])
        if extension not in used:
            used.append(extension)

    def _document(self, uri):
        doc = json.loads(json.dumps(self.doc))
        buffer = {"byteLength": len(self.buffer)}
        if uri:
            buffer["uri"] = "data:application/octet-stream;base64," + base64.b64encode(
                bytes(self.buffer)).decode()
        doc["buffers"] = [buffer]
        return doc

    def gltf_text(self):
        return json.dumps(self._document(uri=True), indent=1)

    def glb_bytes(self):
        text = json.dumps(self._document(uri=False)).encode()
        text += b" " * (-len(text) % 4)
        binary = bytes(self.buffer) + b"\0" * (-len(self.buffer) % 4)
        chunks = (struct.pack("<I4s", len(text), b"JSON") + text +
                  struct.pack("<I4s", len(binary), b"BIN\0") + binary)
        return struct.pack("<4sII", b"glTF", 2, 12 + len(chunks)) + chunks

    def write(self, path):
        path = pathlib.Path(path)
        if path.suffix == ".glb":
            path.write_bytes(self.glb_bytes())
        else:
            path.write_text(self.gltf_text())
        return path


def quad(size, z=0.0):
    """A square of side 2 * size in the plane z, facing +z, as 4 positions."""
    return [-size, -size, z, size, -size, z, size, size, z, -size, size, z]


def red_quad():
    """A red quad of side 2 at z = 0 facing a camera at z = 3 (yfov 0.8 rad: the quad covers
    the image centre, not its corners), lit head-on by a white directional light of 1 lux
    travelling along -z. The centre pixel is diffuse + specular = (1.04, 0.04, 0.04)."""
    g = Gltf()
    red = g.material("red", (1.0, 0.0, 0.0), metallic=0.0, roughness=1.0)
    g.node(name="quad", mesh=g.mesh([{"positions": quad(1.0), "indices": [0, 1, 2, 0, 2, 3],
                                      "material": red,
                                      "normals": [0, 0, 1] * 4, "uvs": [0, 0, 1, 0, 1, 1, 0, 1]}]))
    g.node(name="eye", camera=g.camera(0.8), translation=[0, 0, 3])
    g.node(name="sun", light=g.light("directional", 1.0))
    return g


# The red quad's 2x2 texture: top row red and green, bottom row blue and white.
QUAD_TEXELS = [[(255, 0, 0), (0, 255, 0)], [(0, 0, 255), (255, 255, 255)]]


def textured_quad(how="data"):
    """The red quad, white, printed with QUAD_TEXELS (nearest filter): each quarter of the
    quad shows one texel, head-on, so pixel = 1.05 x texel + the grey glint."""
    g = Gltf()
    printed = g.material("printed", (1.0, 1.0, 1.0), texture=g.texture(
        png_bytes(QUAD_TEXELS), how, uri="quad.png", mag_filter=9728))
    g.node(name="quad", mesh=g.mesh([{"positions": quad(1.0), "indices": [0, 1, 2, 0, 2, 3],
                                      "material": printed, "normals": [0, 0, 1] * 4,
                                      "uvs": [0, 1, 1, 1, 1, 0, 0, 0]}]))
    g.node(name="eye", camera=g.camera(0.8), translation=[0, 0, 3])
    g.node(name="sun", light=g.light("directional", 1.0))
    return g


def cube(size):
    """A cube of side 2 * size about the origin: 8 positions, 12 triangles."""
    s = size
    positions = [-s, -s, -s, s, -s, -s, s, s, -s, -s, s, -s, -s, -s, s, s, -s, s, s, s, s, -s, s, s]
    indices = [0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4,
               3, 6, 2, 3, 7, 6, 0, 4, 7, 0, 7, 3, 1, 2, 6, 1, 6, 5]
    return positions, indices


def animated_hierarchy():
    """Every channel (translation, rotation, scale) with every interpolation (LINEAR, STEP,
    CUBICSPLINE), on a hierarchy: a parent turning about y carries three children; a still
    floor (a strip with vertex colours), a still fan and a matrix node, a camera looking down at them, a point
    and a directional light. One second of animation: 13 frames at 12 frames per second."""
    g = Gltf()
    red = g.material("red", (0.8, 0.1, 0.1), metallic=0.0, roughness=0.4)
    chrome = g.material("chrome", (0.9, 0.9, 0.9), metallic=1.0, roughness=0.1)
    glass = g.material("glass", (1.0, 1.0, 1.0), roughness=0.05, transmission=0.8, ior=1.4)
    floor = g.material("floor", (0.6, 0.6, 0.6), roughness=0.9)
    # The floor: a strip of 4 vertices in y = 0 facing up, painted by vertex colours from
    # warm at the back to cool at the front.
    g.node(name="floor", mesh=g.mesh([{"positions": [-6, 0, -6, -6, 0, 6, 6, 0, -6, 6, 0, 6],
                                       "colors": [1, 0.6, 0.3, 1, 0.3, 0.6, 1, 1, 1, 0.8, 0.2, 1, 0.4, 0.6, 1, 1],
                                       "mode": TRIANGLE_STRIP, "material": floor}]))
    # A still hexagon fan, off to the side, placed by a matrix (scale 0.5, moved).
    hexagon = [0, 0, 0] + [c for k in range(7) for c in
                           (math.cos(k * math.pi / 3), math.sin(k * math.pi / 3), 0)]
    g.node(name="sign", mesh=g.mesh([{"positions": hexagon, "indices": list(range(8)),
                                      "mode": TRIANGLE_FAN, "material": red}]),
           matrix=[0.5, 0, 0, 0, 0, 0.5, 0, 0, 0, 0, 0.5, 0, -3, 1, -3, 1])
    positions, indices = cube(0.4)
    box = g.mesh([{"positions": positions, "indices": indices, "material": red}], name="box")
    shiny = g.mesh([{"positions": positions, "indices": indices, "material": chrome}])
    clear = g.mesh([{"positions": positions, "indices": indices, "material": glass}])
    parent = g.node(name="turntable", translation=[0, 0.5, 0])
    a = g.node(parent, name="a", mesh=box, translation=[1.5, 0, 0])
    b = g.node(parent, name="b", mesh=shiny, translation=[-1.5, 0, 0])
    c = g.node(parent, name="c", mesh=clear, translation=[0, 0, 1.5])
    t = [0.0, 0.5, 1.0]
    # Parent: LINEAR rotation about y, a quarter turn.
    g.animate(parent, "rotation", t, axis_angle([0, 1, 0], 0) + axis_angle([0, 1, 0], 45) +
              axis_angle([0, 1, 0], 90), name="show")
    # a: CUBICSPLINE translation up and back, STEP scale.
    g.animate(a, "translation", [0.0, 1.0], [0, 0, 0, 1.5, 0, 0, 0, 2, 0,
                                            0, 0, 0, 1.5, 0.6, 0, 0, 0, 0], "CUBICSPLINE")
    g.animate(a, "scale", t, [1, 1, 1, 1.3, 0.8, 1.3, 1, 1, 1], "STEP")
    # b: STEP translation, CUBICSPLINE rotation (tangents zero: eased).
    g.animate(b, "translation", t, [-1.5, 0, 0, -1.5, 0.4, 0, -1.5, 0, 0], "STEP")
    g.animate(b, "rotation", [0.0, 1.0], [0, 0, 0, 0] + axis_angle([1, 0, 0], 0) + [0, 0, 0, 0] +
              [0, 0, 0, 0] + axis_angle([1, 0, 0], 60) + [0, 0, 0, 0], "CUBICSPLINE")
    # c: LINEAR scale.
    g.animate(c, "scale", t, [1, 1, 1, 0.6, 1.4, 0.6, 1, 1, 1])
    # A second, shorter animation, chosen by name in tests.
    g.animate(a, "translation", [0.0, 0.25], [1.5, 0, 0, 1.5, 1, 0], animation=1, name="hop")
    # The camera: up and back, looking down 20 degrees.
    g.node(name="eye", camera=g.camera(0.9, name="main"), translation=[0, 2.5, 6],
           rotation=axis_angle([1, 0, 0], -20))
    g.node(name="side", camera=g.camera(0.6, name="side"), translation=[7, 1, 0],
           rotation=axis_angle([0, 1, 0], 90))
    # Photometric, as an exporter writes them (683 lm/W): a 30 W/sr bulb and a 0.3 W/m2 sun.
    g.node(name="bulb", light=g.light("point", 30.0 * 683, (1.0, 0.9, 0.8)), translation=[3, 5, 4])
    g.node(name="sun", light=g.light("directional", 0.3 * 683), rotation=axis_angle([1, -0.3, 0], -60))
    return g


def floor_png():
    """The turntable's floor image: 8 x 8 checkers, light grey and blue."""
    return png_bytes(checker(8, (230, 230, 230), (40, 90, 160)))


def textured_turntable(how="data"):
    """The animated hierarchy, textured: a checkered floor (its image stored `how`), a
    striped box on the turntable (a data URI, repeating twice across each face), and a spot
    light whose cone edge sweeps the floor as it turns. Still camera."""
    g = animated_hierarchy()
    floor_texture = g.texture(floor_png(), how, uri="floor.png")
    stripes = g.texture(png_bytes([[(250, 200, 40), (200, 30, 30)] * 4] * 2), "view" if how == "view" else "data",
                        wrap=(10497, 33648),
                        mag_filter=9728)
    floor = next(i for i, m in enumerate(g.doc["materials"]) if m["name"] == "floor")
    red = next(i for i, m in enumerate(g.doc["materials"]) if m["name"] == "red")
    g.doc["materials"][floor]["pbrMetallicRoughness"]["baseColorTexture"] = {"index": floor_texture}
    g.doc["materials"][red]["pbrMetallicRoughness"]["baseColorTexture"] = {"index": stripes}
    # Texture coordinates for the floor strip (tiled 3 times) and the box (twice per vertex span).
    floor_node = next(n for n in g.doc["nodes"] if n.get("name") == "floor")
    floor_primitive = g.doc["meshes"][floor_node["mesh"]]["primitives"][0]
    floor_primitive["attributes"]["TEXCOORD_0"] = g.accessor([0, 0, 0, 3, 3, 0, 3, 3], "VEC2", target=34962)
    box = next(i for i, m in enumerate(g.doc["meshes"]) if m.get("name") == "box")
    uvs = [0, 0, 2, 0, 2, 2, 0, 2, 0, 2, 2, 2, 2, 0, 0, 0]
    g.doc["meshes"][box]["primitives"][0]["attributes"]["TEXCOORD_0"] = g.accessor(uvs, "VEC2", target=34962)
    # The sign shares the box's material, so it needs coordinates too: its hexagon's own x, y.
    sign = next(n for n in g.doc["nodes"] if n.get("name") == "sign")
    sign_primitive = g.doc["meshes"][sign["mesh"]]["primitives"][0]
    hexagon = g.doc["accessors"][sign_primitive["attributes"]["POSITION"]]
    sign_primitive["attributes"]["TEXCOORD_0"] = g.accessor(
        [0.5, 0.5] + [c for k in range(7) for c in (0.5 + 0.5 * math.cos(k * math.pi / 3),
                                                      0.5 - 0.5 * math.sin(k * math.pi / 3))], "VEC2", target=34962)
    assert hexagon["count"] == 8
    # A spot light on the turntable's arm, pointing down and out: its cone sweeps the floor.
    turntable = next(i for i, n in enumerate(g.doc["nodes"]) if n.get("name") == "turntable")
    spot = g.light("spot", 40.0 * 683, (0.9, 0.9, 1.0))
    g.doc["extensions"]["KHR_lights_punctual"]["lights"][spot]["spot"] = {"innerConeAngle": 0.2,
                                                                         "outerConeAngle": 0.35}
    g.node(turntable, name="spot", light=spot, translation=[0, 3, 2], rotation=axis_angle([1, 0, 0], -70))
    return g


def bump_png(size=16):
    """A tangent-space normal map of ridges along u: codes around (128, 128, 255), x tilting."""
    rows = []
    for y in range(size):
        row = []
        for x in range(size):
            tilt = math.sin(2 * math.pi * x / size) * 0.6
            nz = math.sqrt(1 - tilt * tilt)
            row.append((round((tilt * 0.5 + 0.5) * 255), 128, round((nz * 0.5 + 0.5) * 255)))
        rows.append(row)
    return png_bytes(rows)


def pbr_turntable(how="data"):
    """The textured turntable with every core texture of glTF's material model: the floor
    normal-mapped (generated tangents), its checkers moved by KHR_texture_transform and read
    through TEXCOORD_1; the box's metal and roughness from a texture, its emission through a
    texture and KHR_materials_emissive_strength, its occlusion from one, its slats cut out by
    alpha (MASK) and seen from the front only; the glass box blended (BLEND)."""
    g = textured_turntable(how)
    floor = next(i for i, m in enumerate(g.doc["materials"]) if m["name"] == "floor")
    red = next(i for i, m in enumerate(g.doc["materials"]) if m["name"] == "red")
    bumps = g.texture(bump_png(), "data")
    metal_rough = g.texture(png_bytes([[(0, 40, 255), (0, 230, 0)] * 2] * 2), "data", mag_filter=9728)
    glow = g.texture(png_bytes([[(255, 120, 20), (20, 20, 20)], [(20, 20, 20), (255, 120, 20)]]), "data")
    floor_material = g.doc["materials"][floor]
    floor_material["normalTexture"] = {"index": bumps, "scale": 0.8}
    base = floor_material["pbrMetallicRoughness"]["baseColorTexture"]
    base["texCoord"] = 1
    base["extensions"] = {"KHR_texture_transform": {"offset": [0.1, 0.2], "rotation": 0.3, "scale": [1.5, 1.5]}}
    floor_node = next(n for n in g.doc["nodes"] if n.get("name") == "floor")
    floor_primitive = g.doc["meshes"][floor_node["mesh"]]["primitives"][0]
    floor_primitive["attributes"]["TEXCOORD_1"] = g.accessor([0, 0, 0, 2, 2, 0, 2, 2], "VEC2", target=34962)
    red_material = g.doc["materials"][red]
    red_material["pbrMetallicRoughness"].update({"metallicFactor": 1.0, "roughnessFactor": 1.0,
                                                 "metallicRoughnessTexture": {"index": metal_rough}})
    red_material["emissiveTexture"] = {"index": glow}
    red_material["emissiveFactor"] = [1.0, 1.0, 1.0]
    red_material["occlusionTexture"] = {"index": metal_rough, "strength": 0.5}
    red_material.setdefault("extensions", {})["KHR_materials_emissive_strength"] = {"emissiveStrength": 2.0}
    # The box cut into slats by its base colour's alpha (MASK) and seen from its front only;
    # the glass box half covering what is behind it (BLEND).
    slats = g.texture(png_bytes([[(250, 200, 40, 255), (200, 30, 30, 40)] * 4] * 2), "data", mag_filter=9728)
    red_material["pbrMetallicRoughness"]["baseColorTexture"] = {"index": slats}
    red_material.update({"alphaMode": "MASK", "alphaCutoff": 0.5, "doubleSided": False})
    glass = next(m for m in g.doc["materials"] if m["name"] == "glass")
    glass["pbrMetallicRoughness"]["baseColorFactor"] = [0.6, 0.8, 1.0, 0.5]
    glass["alphaMode"] = "BLEND"
    g._use("KHR_texture_transform")
    g._use("KHR_materials_emissive_strength")
    return g


def uv_sphere(radius, rings, segments):
    """A smooth UV sphere about the origin: positions, normals, uvs, indices (flat lists);
    2 * rings * segments triangles, some degenerate at the poles."""
    positions, normals, uvs, indices = [], [], [], []
    for ring in range(rings + 1):
        theta = math.pi * ring / rings
        for segment in range(segments + 1):
            phi = 2 * math.pi * segment / segments
            normal = (math.sin(theta) * math.cos(phi), math.cos(theta), math.sin(theta) * math.sin(phi))
            normals += normal
            positions += [radius * c for c in normal]
            uvs += [segment / segments, ring / rings]
    for ring in range(rings):
        for segment in range(segments):
            a = ring * (segments + 1) + segment
            b = a + segments + 1
            indices += [a, a + 1, b, a + 1, b + 1, b]
    return positions, normals, uvs, indices


def forest(flattened=False, trees=50, detail=0):
    """One smooth, texture-mapped tree (a cube with normals leaning out and UVs; with
    detail > 0 a UV sphere of about `detail` triangles) placed by `trees` nodes on a
    10 x 5 grid over a floor: every fifth turns and every seventh hops (the first second,
    13 frames at 12 per second), the rest stand still, some turned and scaled. flattened:
    the same scene with one glTF mesh per node, each naming the same accessors, so nothing
    is shared.

        python3 -c "import make_gltf; make_gltf.forest(detail=2000).write('forest100k.gltf')"

    writes a shot of 100,000 triangles (50 x 2,000) for benchmarks."""
    g = Gltf()
    bark = g.material("bark", (0.2, 0.6, 0.2), roughness=0.5)
    floor = g.material("floor", (0.6, 0.6, 0.6), roughness=0.9)
    g.node(name="floor", mesh=g.mesh([{"positions": [-8, 0, -8, -8, 0, 8, 8, 0, -8, 8, 0, 8],
                                       "mode": TRIANGLE_STRIP, "material": floor}]))
    if detail > 0:
        segments = max(4, round(math.sqrt(detail)))
        positions, normals, uvs, indices = uv_sphere(0.35, max(2, math.ceil(detail / (2 * segments))), segments)
        primitive = {"positions": positions, "indices": indices, "material": bark, "normals": normals, "uvs": uvs}
    else:
        positions, indices = cube(0.3)
        primitive = {"positions": positions, "indices": indices, "material": bark,
                     "normals": [c / (0.3 * math.sqrt(3)) for c in positions],
                     "uvs": [0, 0, 1, 0, 1, 1, 0, 1, 0, 1, 1, 1, 1, 0, 0, 0]}
    tree = g.mesh([primitive], name="tree")
    for i in range(trees):
        mesh = tree
        if flattened and i > 0:  # another glTF mesh over the very same accessors
            g.doc["meshes"].append(json.loads(json.dumps(g.doc["meshes"][tree])))
            mesh = len(g.doc["meshes"]) - 1
        x, z = -6 + (i % 10) * 1.3, -4 + (i // 10) * 1.6
        node = g.node(name="tree%d" % i, mesh=mesh, translation=[x, 0.3 + 0.1 * (i % 3), z],
                      rotation=axis_angle([0, 1, 0], 7 * i), scale=[1, 1 + 0.2 * (i % 4), 1])
        if i % 5 == 0:
            g.animate(node, "rotation", [0.0, 1.0], axis_angle([0, 1, 0], 7 * i) + axis_angle([0, 1, 0], 7 * i + 90))
        if i % 7 == 0:
            g.animate(node, "translation", [0.0, 0.5, 1.0],
                      [x, 0.3, z, x, 1.2, z, x, 0.3, z])
    g.node(name="eye", camera=g.camera(0.9, name="main"), translation=[0, 5, 8],
           rotation=axis_angle([1, 0, 0], -32))
    g.node(name="bulb", light=g.light("point", 40.0, (1.0, 0.9, 0.8)), translation=[2, 6, 4])
    g.node(name="sun", light=g.light("directional", 0.3), rotation=axis_angle([1, -0.3, 0], -60))
    return g


def mirror_set():
    """A mirror (a smooth metal, reflectivity 1) standing on a still floor, facing a camera
    2 in front of it at eye height, and a point light over the camera: what moves behind
    the camera is seen only in the mirror."""
    g = Gltf()
    mirror = g.material("mirror", (0.95, 0.95, 0.95), metallic=1.0, roughness=0.0)
    floor = g.material("floor", (0.5, 0.5, 0.5), roughness=0.9)
    g.node(name="floor", mesh=g.mesh([{"positions": [-6, 0, -6, -6, 0, 6, 6, 0, -6, 6, 0, 6],
                                       "mode": TRIANGLE_STRIP, "material": floor}]))
    g.node(name="mirror", mesh=g.mesh([{"positions": quad(1.5), "indices": [0, 1, 2, 0, 2, 3],
                                        "material": mirror}]), translation=[0, 1.6, -2])
    g.node(name="eye", camera=g.camera(0.7), translation=[0, 1.6, 2])
    g.node(name="bulb", light=g.light("point", 25.0), translation=[1, 4, 2])
    return g


def seen_in_a_mirror():
    """A cube that spins and hops behind the camera, seen only in a mirror (a smooth metal,
    reflectivity 1) that faces the camera over a still floor. One second, 13 frames at 12
    per second."""
    g = mirror_set()
    red = g.material("red", (0.8, 0.1, 0.1), roughness=0.6)
    positions, indices = cube(0.3)
    cube_node = g.node(name="cube", mesh=g.mesh([{"positions": positions, "indices": indices, "material": red}]),
                       translation=[0, 1.4, 3.5])
    g.animate(cube_node, "rotation", [0.0, 1.0], axis_angle([0, 1, 0], 0) + axis_angle([0, 1, 0], 120))
    g.animate(cube_node, "translation", [0.0, 0.5, 1.0], [0, 1.4, 3.5, 0.3, 2.0, 3.5, 0, 1.4, 3.5], "STEP")
    return g


def translation_matrix(x, y, z):
    """glTF's column-major 4x4 matrix of a translation."""
    return [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, x, y, z, 1]


def tube(length, radius, sides, rings, blend):
    """A tube along +x from 0 to length with capped ends, smooth: positions, normals,
    indices, and per vertex the joints and weights that bind its first half to joint 0 and
    its second half to joint 1, blended over `blend` either side of the middle;
    2 * sides * (rings + 1) triangles."""
    positions, normals, joints, weights, indices = [], [], [], [], []

    def vertex(x, y, z, normal):
        t = min(1.0, max(0.0, (x - (length / 2 - blend)) / (2 * blend)))
        positions.extend((x, y, z))
        normals.extend(normal)
        # A joint with no weight is numbered 0, as the validator asks.
        joints.extend((0, 1 if t > 0 else 0, 0, 0))
        weights.extend((1 - t, t, 0, 0))
        return len(positions) // 3 - 1

    ring_start = []
    for ring in range(rings + 1):
        ring_start.append(len(positions) // 3)
        for side in range(sides):
            angle = 2 * math.pi * side / sides
            c, s = math.cos(angle), math.sin(angle)
            vertex(length * ring / rings, radius * c, radius * s, (0, c, s))
    for ring in range(rings):
        for side in range(sides):
            a, b = ring_start[ring] + side, ring_start[ring] + (side + 1) % sides
            c, d = a + sides, b + sides
            indices += [a, b, d, a, d, c]
    for x, facing in ((0.0, -1), (length, 1)):  # the caps: fans with normals along the axis
        centre = vertex(x, 0, 0, (facing, 0, 0))
        rim = [vertex(x, radius * math.cos(2 * math.pi * k / sides), radius * math.sin(2 * math.pi * k / sides),
                      (facing, 0, 0)) for k in range(sides)]
        for k in range(sides):
            pair = (rim[k], rim[(k + 1) % sides]) if facing > 0 else (rim[(k + 1) % sides], rim[k])
            indices += [centre, *pair]
    return positions, normals, indices, joints, weights


def add_arm(g, material, shoulder, length=2.0, radius=0.25, sides=8, rings=24, degrees=(0, 60, 100)):
    """A skinned arm: a tube of `length` along +x from `shoulder`, bound to a still shoulder
    joint and an elbow joint half way, which bends it up about z by `degrees` at 0, 0.5 and
    1 s. Returns the nodes (mesh, shoulder, elbow)."""
    positions, normals, indices, joints, weights = tube(length, radius, sides, rings, blend=0.15 * length)
    x0, y0, z0 = shoulder
    positions = [v + (x0, y0, z0)[i % 3] for i, v in enumerate(positions)]  # bind pose in world space
    mesh = g.mesh([{"positions": positions, "normals": normals, "indices": indices, "material": material,
                    "joints": joints, "weights": weights}], name="arm")
    shoulder_node = g.node(name="shoulder", translation=list(shoulder))
    elbow = g.node(shoulder_node, name="elbow", translation=[length / 2, 0, 0])
    skin = g.skin([shoulder_node, elbow], [translation_matrix(-x0, -y0, -z0),
                                           translation_matrix(-x0 - length / 2, -y0, -z0)])
    # The skinned mesh's node is a root without a transform of its own (glTF ignores it).
    arm = g.node(name="arm", mesh=mesh, skin=skin)
    g.animate(elbow, "rotation", [0.0, 0.5, 1.0], [q for d in degrees for q in axis_angle([0, 0, 1], d)])
    return arm, shoulder_node, elbow


def skinned_arm(detail=0):
    """A skinned arm (a tube of 400 triangles, or at least `detail`)
    bending at the elbow in front of a still wall, lit by a point light. One second: 13
    frames at 12 per second.

        python3 -c "import make_gltf; make_gltf.skinned_arm(detail=50000).write('arm50k.gltf')"

    writes a skinned mesh of 50,000 triangles and more for benchmarks."""
    g = Gltf()
    skin = g.material("skin", (0.8, 0.45, 0.3), roughness=0.5)
    wall = g.material("wall", (0.7, 0.7, 0.65), roughness=0.9)
    g.node(name="wall", mesh=g.mesh([{"positions": [-4, -1, -1.5, 4, -1, -1.5, 4, 4, -1.5, -4, 4, -1.5],
                                      "indices": [0, 1, 2, 0, 2, 3], "material": wall}]))
    sides, rings = 8, 24
    if detail > 0:
        sides = 64
        rings = max(1, math.ceil(detail / (2 * sides)) - 1)
    add_arm(g, skin, (-1.0, 0.8, 0.0), sides=sides, rings=rings)
    g.node(name="eye", camera=g.camera(0.8), translation=[0, 1.2, 5])
    g.node(name="bulb", light=g.light("point", 30.0, (1.0, 0.95, 0.9)), translation=[2, 3, 3])
    return g


def smooth_normals(positions, indices):
    """Unit vertex normals of a triangle mesh: the area-weighted normals of the triangles
    around each position (vertices at the same position, as on a UV seam, share one)."""
    sums = {}
    keys = [tuple(round(c, 9) for c in positions[i:i + 3]) for i in range(0, len(positions), 3)]
    for t in range(0, len(indices), 3):
        a, b, c = (positions[3 * i:3 * i + 3] for i in indices[t:t + 3])
        u, v = [b[k] - a[k] for k in range(3)], [c[k] - a[k] for k in range(3)]
        n = (u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0])
        for i in indices[t:t + 3]:
            total = sums.setdefault(keys[i], [0.0, 0.0, 0.0])
            for k in range(3):
                total[k] += n[k]
    normals = []
    for key in keys:
        n = sums.get(key, [0.0, 1.0, 0.0])
        length = math.sqrt(sum(c * c for c in n)) or 1.0
        normals += [c / length for c in n]
    return normals


def blob_targets(positions, indices):
    """Two morph targets of a sphere about the origin: `tall` (stretched along y, squeezed
    across) and `bumpy` (three bulges round its waist), each with the normal deltas that
    turn the sphere's normals into the morphed mesh's."""
    normals = smooth_normals(positions, indices)
    tall, bumpy = [], []
    for i in range(0, len(positions), 3):
        x, y, z = positions[i:i + 3]
        nx, ny, nz = normals[i:i + 3]
        tall += [-0.25 * x, 0.6 * y, -0.25 * z]
        bulge = 0.15 * math.sin(3 * math.atan2(nz, nx)) * math.sqrt(max(0.0, 1 - ny * ny))
        bumpy += [bulge * nx, bulge * ny, bulge * nz]
    targets = []
    for deltas in (tall, bumpy):
        morphed = smooth_normals([p + d for p, d in zip(positions, deltas)], indices)
        targets.append({"positions": deltas, "normals": [m - n for m, n in zip(morphed, normals)]})
    return normals, targets


def morphing_blob():
    """A sphere-ish blob of 3,072 triangles with two morph targets
    (tall, bumpy) animated by one CUBICSPLINE weights channel, above a floor it casts a
    shadow on, under a point light. One second: 13 frames at 12 per second."""
    g = Gltf()
    clay = g.material("clay", (0.3, 0.5, 0.8), roughness=0.4)
    floor = g.material("floor", (0.6, 0.6, 0.6), roughness=0.9)
    g.node(name="floor", mesh=g.mesh([{"positions": [-5, 0, -5, -5, 0, 5, 5, 0, -5, 5, 0, 5],
                                       "mode": TRIANGLE_STRIP, "material": floor}]))
    positions, _, _, indices = uv_sphere(0.6, 32, 48)
    normals, targets = blob_targets(positions, indices)
    blob = g.node(name="blob", translation=[0, 1.1, 0], mesh=g.mesh(
        [{"positions": positions, "normals": normals, "indices": indices, "material": clay,
          "targets": targets}], name="blob", weights=[0, 0]))
    # Per key: in-tangents (tall, bumpy), values, out-tangents; tangents per second.
    g.animate(blob, "weights", [0.0, 0.5, 1.0],
              [0, 0, 0, 0, 2, 0,
               0, 2, 1, 0.5, 0, 2,
               -1, 1, 0.3, 1, 0, 0], "CUBICSPLINE")
    g.node(name="eye", camera=g.camera(0.8), translation=[0, 2.2, 4.5], rotation=axis_angle([1, 0, 0], -15))
    g.node(name="bulb", light=g.light("point", 40.0), translation=[1.5, 4, 1])
    return g


def skinned_in_a_mirror():
    """The skinned arm bends behind the camera, seen only in a
    mirror (a smooth metal, reflectivity 1) that faces the camera over a still floor. One
    second, 13 frames at 12 per second."""
    g = mirror_set()
    add_arm(g, g.material("skin", (0.8, 0.45, 0.3), roughness=0.5), (-1.0, 1.2, 3.0))
    return g


EXAMPLES = {"red_quad.gltf": red_quad, "red_quad.glb": red_quad,
            "animated_hierarchy.gltf": animated_hierarchy,
            "textured_quad.gltf": textured_quad, "textured_quad.glb": lambda: textured_quad("view"),
            "textured_turntable.gltf": textured_turntable,
            "textured_turntable.glb": lambda: textured_turntable("view"),
            "forest.gltf": forest, "forest_flattened.gltf": lambda: forest(flattened=True),
            "seen_in_a_mirror.gltf": seen_in_a_mirror,
            "skinned_arm.gltf": skinned_arm, "morphing_blob.gltf": morphing_blob,
            "skinned_in_a_mirror.gltf": skinned_in_a_mirror}


def main(argv):
    if len(argv) != 2:
        sys.exit("usage: make_gltf.py OUT_DIR")
    out = pathlib.Path(argv[1])
    out.mkdir(parents=True, exist_ok=True)
    for name, make in EXAMPLES.items():
        print(make().write(out / name))


if __name__ == "__main__":
    main(sys.argv)
