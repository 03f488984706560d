"""Writes the glTF files that tests/reference/compare.py renders with the tracer and with
the Khronos glTF Sample Renderer: one material feature each, seen by the file's camera and
lit by one or two punctual lights, on geometry that casts few shadows on itself (the
Sample Renderer has none). Also copies the glTF 2.0 models Debian's assimp-testmodels
ships that use plain PBR materials, with a camera and lights added.

    python3 tests/reference/make_assets.py OUT_DIR     # writes OUT_DIR/NAME/NAME.gltf

Pure Python beyond tests/gltf/make_gltf.py; textures are PNG files beside each .gltf.
"""
import json
import math
import pathlib
import shutil
import struct
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent.parent / "gltf"))
from make_gltf import FLOAT, Gltf, png_bytes, quad, uv_sphere  # noqa: E402

ASSIMP_GLTF2 = pathlib.Path("/usr/share/assimp/models/glTF2")
YFOV = 0.7  # radians; the aspect ratio is the image's (cameras say none)
LINEAR, REPEAT = 9729, 10497


def look_at(eye, target):
    """The glTF rotation [x, y, z, w] of a camera at eye looking at target, +y up."""
    f = _normalize([t - e for t, e in zip(target, eye)])
    r = _normalize(_cross(f, [0.0, 1.0, 0.0]))
    u = _cross(r, f)
    # Columns of the rotation: r, u, -f (a glTF camera looks along its -z).
    m = [[r[0], u[0], -f[0]], [r[1], u[1], -f[1]], [r[2], u[2], -f[2]]]
    return _quaternion(m)


def _quaternion(m):
    trace = m[0][0] + m[1][1] + m[2][2]
    if trace > 0:
        s = 2 * math.sqrt(trace + 1)
        return [(m[2][1] - m[1][2]) / s, (m[0][2] - m[2][0]) / s, (m[1][0] - m[0][1]) / s, s / 4]
    i = max(range(3), key=lambda k: m[k][k])
    j, k = (i + 1) % 3, (i + 2) % 3
    s = 2 * math.sqrt(1 + m[i][i] - m[j][j] - m[k][k])
    q = [0.0] * 4
    q[i] = s / 4
    q[j] = (m[j][i] + m[i][j]) / s
    q[k] = (m[k][i] + m[i][k]) / s
    q[3] = (m[k][j] - m[j][k]) / s
    return q


def _normalize(v):
    length = math.sqrt(sum(c * c for c in v))
    return [c / length for c in v]


def _cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


class Asset(Gltf):
    """A Gltf with what these assets need beyond the importer tests' files: any material,
    float texture coordinates (two sets), tangents, cameras aimed at a point, light ranges
    and spot cones, and textures as files beside the .gltf."""

    def __init__(self, name):
        super().__init__()
        self.name = name
        self.doc["asset"]["generator"] = "tcfarm tests/reference/make_assets.py"
        self.files = {}  # file name -> bytes, written beside the .gltf

    def use(self, extension):
        self._use(extension)

    def image_texture(self, file_name, rows, repeat=False):
        """A texture of an 8-bit RGB or RGBA PNG (rows of texel tuples), linear filtering."""
        self.files[file_name] = rgba_png(rows) if len(rows[0][0]) == 4 else png_bytes(rows)
        wrap = REPEAT if repeat else 33071  # CLAMP_TO_EDGE
        sampler = self._add("samplers", {"magFilter": LINEAR, "minFilter": LINEAR,
                                         "wrapS": wrap, "wrapT": wrap})
        return self._add("textures", {"source": self._add("images", {"uri": file_name}),
                                      "sampler": sampler})

    def pbr(self, name, base=(0.8, 0.8, 0.8, 1.0), metallic=0.0, roughness=0.5, **fields):
        """A material: pbrMetallicRoughness factors, plus `pbr` (more of that object) and
        any top-level fields (normalTexture, emissive..., alphaMode, extensions)."""
        pbr = {"baseColorFactor": list(base) + [1.0] * (4 - len(base)), "metallicFactor": metallic,
               "roughnessFactor": roughness, **fields.pop("pbr", {})}
        for extension in fields.get("extensions", {}):
            self._use(extension)
        return self._add("materials", {"name": name, "pbrMetallicRoughness": pbr, **fields})

    def primitive(self, positions, normals, indices, material, uv0=None, uv1=None, tangents=None):
        attributes = {"POSITION": self.accessor(positions, "VEC3", target=34962, bounds=True),
                      "NORMAL": self.accessor(normals, "VEC3", target=34962)}
        for name, values in (("TEXCOORD_0", uv0), ("TEXCOORD_1", uv1)):
            if values is not None:
                attributes[name] = self.accessor(values, "VEC2", FLOAT, target=34962)
        if tangents is not None:
            attributes["TANGENT"] = self.accessor(tangents, "VEC4", FLOAT, target=34962)
        return {"attributes": attributes, "material": material,
                "indices": self.accessor(indices, "SCALAR", 5125, target=34963)}

    def add_mesh(self, primitives, **node):
        return self.node(mesh=self._add("meshes", {"primitives": primitives}), **node)

    def aim_camera(self, eye, target, yfov=YFOV):
        camera = self._add("cameras", {"type": "perspective", "perspective": {"yfov": yfov, "znear": 0.05}})
        return self.node(name="camera", camera=camera, translation=list(eye), rotation=look_at(eye, target))

    def punctual(self, type_, intensity, color=(1.0, 1.0, 1.0), at=None, toward=None, range_=None,
                 cone=None):
        """A light and its node: at (position) for point and spot lights, toward (a point the
        spot or directional light shines at), range_, cone (inner, outer angles)."""
        light = self.light(type_, intensity, color)
        record = self.doc["extensions"]["KHR_lights_punctual"]["lights"][light]
        if range_ is not None:
            record["range"] = range_
        if cone is not None:
            record["spot"] = {"innerConeAngle": cone[0], "outerConeAngle": cone[1]}
        node = {"name": f"{type_} light"}
        origin = list(at) if at is not None else [0.0, 0.0, 0.0]
        if at is not None:
            node["translation"] = origin
        if toward is not None:
            if at is None:  # a directional light: only its direction matters
                origin = [-c for c in toward]
                toward = [0.0, 0.0, 0.0]
            node["rotation"] = look_at(origin, toward)
        return self.node(light=light, **node)

    def write_to(self, folder):
        folder = pathlib.Path(folder) / self.name
        folder.mkdir(parents=True, exist_ok=True)
        for file_name, data in self.files.items():
            (folder / file_name).write_bytes(data)
        return self.write(folder / f"{self.name}.gltf")


def rgba_png(rows):
    """An 8-bit RGBA PNG of rows of (r, g, b, a) codes, top row first."""
    import zlib

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    height, width = len(rows), len(rows[0])
    raw = b"".join(b"\0" + bytes(c for texel in row for c in texel) for row in rows)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 6, 0, 0, 0)) +
            chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


# --- geometry -------------------------------------------------------------------------------

def sphere(radius=1.0, rings=24, segments=48):
    """A UV sphere: positions, normals, uvs, indices, tangents (along +u, w = 1)."""
    positions, normals, uvs, indices = uv_sphere(radius, rings, segments)
    tangents = []
    for ring in range(rings + 1):
        for segment in range(segments + 1):
            phi = 2 * math.pi * segment / segments
            tangents += [-math.sin(phi), 0.0, math.cos(phi), 1.0]
    return positions, normals, uvs, indices, tangents


def panel(width, height, z=0.0):
    """A rectangle in the plane z facing +z: positions, normals, uvs (v down the image, as
    glTF's are), indices, tangents (+x, w = 1)."""
    positions = [-width / 2, -height / 2, z, width / 2, -height / 2, z,
                 width / 2, height / 2, z, -width / 2, height / 2, z]
    return positions, [0, 0, 1] * 4, [0, 1, 1, 1, 1, 0, 0, 0], [0, 1, 2, 0, 2, 3], [1, 0, 0, 1] * 4


def sphere_primitive(g, material, with_tangents=False):
    positions, normals, uvs, indices, tangents = sphere()
    return g.primitive(positions, normals, indices, material, uv0=uvs,
                       tangents=tangents if with_tangents else None)


def panel_primitive(g, material, width=2.0, height=2.0, z=0.0, **extra):
    positions, normals, uvs, indices, tangents = panel(width, height, z)
    return g.primitive(positions, normals, indices, material, uv0=extra.pop("uv0", uvs), **extra)


# --- textures ------------------------------------------------------------------------------

def quadrants(size, colours):
    """size x size texels, four quadrants of colours (top left, top right, bottom left,
    bottom right) and a small marker in the top left corner that shows any mirroring."""
    rows = []
    for y in range(size):
        row = []
        for x in range(size):
            quadrant = (y >= size // 2) * 2 + (x >= size // 2)
            row.append(colours[quadrant])
        rows.append(row)
    for y in range(size // 8):
        for x in range(size // 4):
            rows[y][x] = (255, 255, 255)[:len(colours[0])] + (255,) * (len(colours[0]) - 3)
    return rows


def bump_normals(size, bumps):
    """A tangent-space normal map of bumps x bumps round domes (RGB, +y up the image)."""
    rows = []
    cell = size / bumps
    for y in range(size):
        row = []
        for x in range(size):
            u = ((x + 0.5) % cell) / cell * 2 - 1
            v = -(((y + 0.5) % cell) / cell * 2 - 1)  # +y is up the image
            r2 = u * u + v * v
            if r2 < 0.8:
                n = _normalize([u * 0.8, v * 0.8, 1.0])
            else:
                n = [0.0, 0.0, 1.0]
            row.append(tuple(round((c * 0.5 + 0.5) * 255) for c in n))
        rows.append(row)
    return rows


# --- the assets ----------------------------------------------------------------------------

def metal_rough_spheres():
    """Metallic 0, 0.5, 1 (rows, top to bottom) by roughness 0.25 to 1 (columns)."""
    g = Asset("metal_rough_spheres")
    for row, metallic in enumerate((0.0, 0.5, 1.0)):
        for column, roughness in enumerate((0.25, 0.45, 0.65, 0.85, 1.0)):
            material = g.pbr(f"m{metallic}_r{roughness}", (0.9, 0.45, 0.2), metallic, roughness)
            g.add_mesh([sphere_primitive(g, material)], translation=[(column - 2) * 2.3, (1 - row) * 2.3, 0],
                       scale=[0.95] * 3)
    g.aim_camera([0, 0, 13.5], [0, 0, 0])
    g.punctual("directional", 2.5, toward=[-0.4, -0.5, -1.0])
    g.punctual("point", 60.0, (0.8, 0.9, 1.0), at=[4, 4, 6])
    return g


def metal_rough_texture():
    """A sphere whose metallicRoughnessTexture is four quadrants (metal B, roughness G)."""
    g = Asset("metal_rough_texture")
    texture = g.image_texture("metal_rough.png", quadrants(16, [(0, 60, 0), (0, 200, 0),
                                                               (0, 60, 255), (0, 200, 255)]))
    material = g.pbr("textured metal", (0.95, 0.8, 0.5), 1.0, 1.0,
                     pbr={"metallicRoughnessTexture": {"index": texture}})
    g.add_mesh([sphere_primitive(g, material)], rotation=[0, 0.3826834, 0, 0.9238795])
    g.aim_camera([0, 0.8, 3.6], [0, 0, 0])
    g.punctual("point", 30.0, at=[2, 2.5, 3], range_=20.0)
    g.punctual("directional", 1.0, toward=[1, -0.3, -1])
    return g


def base_color_texcoord1():
    """A panel textured through TEXCOORD_1 (TEXCOORD_0 is the mirror image, so using the
    wrong set shows)."""
    g = Asset("base_color_texcoord1")
    texture = g.image_texture("quadrants.png", quadrants(8, [(230, 40, 40), (40, 200, 40),
                                                            (40, 60, 230), (230, 220, 60)]))
    material = g.pbr("texcoord 1", (1, 1, 1), 0.0, 0.7, pbr={"baseColorTexture": {"index": texture, "texCoord": 1}})
    positions, normals, uvs, indices, _ = panel(3.0, 2.2)
    mirrored = [1 - u if i % 2 == 0 else u for i, u in enumerate(uvs)]
    g.add_mesh([g.primitive(positions, normals, indices, material, uv0=mirrored, uv1=uvs)])
    g.aim_camera([0, 0, 4.2], [0, 0, 0])
    g.punctual("spot", 40.0, at=[0.5, 0.8, 3.0], toward=[0, 0, 0], range_=10.0, cone=(0.5, 0.9))
    return g


def normal_map(with_tangents):
    """A panel with a normal map of domes, lit from the upper left at a grazing angle."""
    name = "normal_map_tangents" if with_tangents else "normal_map_no_tangents"
    g = Asset(name)
    texture = g.image_texture("bumps.png", bump_normals(64, 4))
    material = g.pbr("bumpy", (0.7, 0.7, 0.75), 0.0, 0.5, normalTexture={"index": texture})
    positions, normals, uvs, indices, tangents = panel(3.0, 2.2)
    g.add_mesh([g.primitive(positions, normals, indices, material, uv0=uvs,
                            tangents=tangents if with_tangents else None)])
    g.aim_camera([0, -0.6, 4.0], [0, 0, 0])
    g.punctual("directional", 3.0, toward=[1.0, -1.0, -0.8])
    return g


def emissive_strength():
    """A dark panel whose emissiveTexture glows, times emissiveFactor and
    KHR_materials_emissive_strength 4."""
    g = Asset("emissive_strength")
    texture = g.image_texture("glow.png", quadrants(8, [(255, 128, 0), (0, 128, 255),
                                                       (60, 255, 60), (255, 255, 255)]))
    material = g.pbr("glowing", (0.05, 0.05, 0.05), 0.0, 0.8,
                     emissiveTexture={"index": texture}, emissiveFactor=[0.5, 0.4, 0.3],
                     extensions={"KHR_materials_emissive_strength": {"emissiveStrength": 4.0}})
    g.add_mesh([panel_primitive(g, material, 3.0, 2.2)])
    g.aim_camera([0.5, 0.3, 4.0], [0, 0, 0])
    g.punctual("point", 8.0, at=[-1, 1, 2])
    return g


def texture_transform():
    """A panel's base colour texture moved by KHR_texture_transform: offset, rotation and
    scale on a repeating texture."""
    g = Asset("texture_transform")
    texture = g.image_texture("quadrants.png", quadrants(8, [(230, 40, 40), (40, 200, 40),
                                                            (40, 60, 230), (230, 220, 60)]), repeat=True)
    g.use("KHR_texture_transform")
    transform = {"offset": [0.2, -0.1], "rotation": 0.5, "scale": [1.6, 1.3]}
    material = g.pbr("transformed", (1, 1, 1), 0.0, 0.8, pbr={
        "baseColorTexture": {"index": texture, "extensions": {"KHR_texture_transform": transform}}})
    g.add_mesh([panel_primitive(g, material, 3.0, 2.2)])
    g.aim_camera([0, 0, 4.2], [0, 0, 0])
    g.punctual("directional", 2.0, toward=[0.2, -0.3, -1])
    return g


def backdrop(g, z=-1.0):
    """A grey wall behind the subject, so that what should be see-through shows it."""
    wall = g.pbr("backdrop", (0.5, 0.5, 0.5), 0.0, 1.0)
    g.add_mesh([panel_primitive(g, wall, 8.0, 6.0, z=z)])


def alpha_mask():
    """A panel cut out by its base colour alpha (MASK at 0.5) in front of a wall."""
    g = Asset("alpha_mask")
    rows = [[(220, 80, 40, 255 if (x // 4 + y // 4) % 2 == 0 else round(255 * (x / 15) * 0.45))
             for x in range(16)] for y in range(16)]
    texture = g.image_texture("cutout.png", rows)
    material = g.pbr("cut out", (1, 1, 1), 0.0, 0.6, pbr={"baseColorTexture": {"index": texture}},
                     alphaMode="MASK", alphaCutoff=0.5)
    g.add_mesh([panel_primitive(g, material, 3.0, 2.2)])
    backdrop(g)
    g.aim_camera([0, 0, 4.2], [0, 0, 0])
    g.punctual("directional", 2.0, toward=[0, 0, -1])
    return g


def alpha_blend():
    """A panel blended over a wall: alpha from its texture (a ramp) times its factor."""
    g = Asset("alpha_blend")
    rows = [[(40, 120, 230, round(255 * x / 15)) for x in range(16)] for _ in range(16)]
    texture = g.image_texture("ramp.png", rows)
    material = g.pbr("see-through", (1, 1, 1, 0.8), 0.0, 0.6, pbr={"baseColorTexture": {"index": texture}},
                     alphaMode="BLEND")
    g.add_mesh([panel_primitive(g, material, 3.0, 2.2)])
    backdrop(g)
    g.aim_camera([0, 0, 4.2], [0, 0, 0])
    g.punctual("directional", 2.0, toward=[0, 0, -1])
    return g


def double_sided():
    """Two panels seen from behind, in front of a wall: the left one double-sided (drawn,
    shaded with its normal turned to the camera), the right one not (not drawn)."""
    g = Asset("double_sided")
    two = g.pbr("two-sided", (0.2, 0.8, 0.3), 0.0, 0.6, doubleSided=True)
    one = g.pbr("one-sided", (0.8, 0.2, 0.3), 0.0, 0.6)
    behind = [0, 1, 0, 0]  # half a turn about y: the panel faces -z, away from the camera
    g.add_mesh([panel_primitive(g, two, 1.6, 2.0)], translation=[-1.0, 0, 0], rotation=behind)
    g.add_mesh([panel_primitive(g, one, 1.6, 2.0)], translation=[1.0, 0, 0], rotation=behind)
    backdrop(g)
    g.aim_camera([0, 0, 4.2], [0, 0, 0])
    g.punctual("point", 25.0, at=[0, 1.5, 3], range_=12.0)
    return g


def unlit():
    """An unlit sphere (KHR_materials_unlit: its base colour as it is) beside a lit one."""
    g = Asset("unlit")
    flat = g.pbr("unlit", (0.2, 0.5, 0.9), 0.0, 1.0, extensions={"KHR_materials_unlit": {}})
    lit = g.pbr("lit", (0.2, 0.5, 0.9), 0.0, 0.5)
    g.add_mesh([sphere_primitive(g, flat)], translation=[-1.2, 0, 0])
    g.add_mesh([sphere_primitive(g, lit)], translation=[1.2, 0, 0])
    g.aim_camera([0, 0, 6], [0, 0, 0])
    g.punctual("directional", 2.0, toward=[-0.5, -0.5, -1])
    return g


def ior():
    """Three glossy dielectric spheres of KHR_materials_ior 1.0 (no reflection), 1.5 (the
    default) and 2.5."""
    g = Asset("ior")
    for column, index in enumerate((1.0, 1.5, 2.5)):
        material = g.pbr(f"ior {index}", (0.1, 0.25, 0.1), 0.0, 0.35,
                         extensions={"KHR_materials_ior": {"ior": index}})
        g.add_mesh([sphere_primitive(g, material)], translation=[(column - 1) * 2.3, 0, 0])
    g.aim_camera([0, 0.5, 7], [0, 0, 0])
    g.punctual("spot", 80.0, at=[0, 3, 4], toward=[0, 0, 0], range_=15.0, cone=(0.6, 1.0))
    g.punctual("directional", 1.5, toward=[0.6, -0.4, -1])
    return g


def clearcoat():
    """KHR_materials_clearcoat over a rough red dielectric: clearcoat 0, 0.5, 1 (rows, top
    to bottom) by clearcoat roughness 0.15 to 1 (columns)."""
    g = Asset("clearcoat")
    for row, factor in enumerate((0.0, 0.5, 1.0)):
        for column, roughness in enumerate((0.15, 0.3, 0.5, 0.75, 1.0)):
            material = g.pbr(f"cc{factor}_r{roughness}", (0.8, 0.08, 0.06), 0.0, 0.8, extensions={
                "KHR_materials_clearcoat": {"clearcoatFactor": factor, "clearcoatRoughnessFactor": roughness}})
            g.add_mesh([sphere_primitive(g, material)], translation=[(column - 2) * 2.3, (1 - row) * 2.3, 0],
                       scale=[0.95] * 3)
    g.aim_camera([0, 0, 13.5], [0, 0, 0])
    g.punctual("directional", 2.5, toward=[-0.4, -0.5, -1.0])
    g.punctual("point", 60.0, (0.8, 0.9, 1.0), at=[4, 4, 6])
    return g


ASSETS = [metal_rough_spheres, metal_rough_texture, base_color_texcoord1,
          lambda: normal_map(True), lambda: normal_map(False), emissive_strength, texture_transform,
          alpha_mask, alpha_blend, double_sided, unlit, ior, clearcoat]


# --- Debian's models -----------------------------------------------------------------------

# (name, file under ASSIMP_GLTF2, camera eye and target, lights as punctual() arguments).
# Models with only the core metallic-roughness material (and KHR_texture_transform).
DEBIAN_MODELS = [
    ("debian_box_textured", "BoxTextured-glTF/BoxTextured.gltf", ([1.6, 1.2, 2.2], [0, 0, 0]),
     [("directional", 2.5, {"toward": [-0.5, -0.8, -1.0]}), ("point", 10.0, {"at": [2, 0.5, 2.5]})]),
    ("debian_box_texcoords", "BoxTexcoords-glTF/boxTexcoords.gltf", ([2.6, 2.0, 3.8], [0, 0, 0]),
     [("directional", 2.5, {"toward": [-0.5, -0.8, -1.0]})]),
    ("debian_texture_transform", "textureTransform/TextureTransformTest.gltf", ([0, 0, 3.4], [0, 0, 0]),
     [("directional", 2.5, {"toward": [0.1, -0.2, -1.0]})]),
]


def debian_model(name, relative, view, lights):
    """The model's file with a camera and lights added, and the files it names copied."""
    source = ASSIMP_GLTF2 / relative
    if not source.exists():
        return None
    doc = json.loads(source.read_text())
    g = Asset(name)
    g.doc = doc
    doc.setdefault("scenes", [{"nodes": []}])
    doc.setdefault("scene", 0)
    for entry in doc.get("buffers", []) + doc.get("images", []):
        uri = entry.get("uri", "")
        if uri and not uri.startswith("data:"):
            g.files[uri] = (source.parent / uri).read_bytes()
    g.aim_camera(*view)
    for type_, intensity, where in lights:
        g.punctual(type_, intensity, **where)
    return g


def write_debian_model(g, folder):
    folder = pathlib.Path(folder) / g.name
    folder.mkdir(parents=True, exist_ok=True)
    for file_name, data in g.files.items():
        (folder / file_name).write_bytes(data)
    path = folder / f"{g.name}.gltf"
    path.write_text(json.dumps(g.doc, indent=1))
    return path


def write_all(folder):
    """Writes every asset under folder; returns {name: path of its .gltf}."""
    folder = pathlib.Path(folder)
    written = {}
    for make in ASSETS:
        g = make()
        written[g.name] = g.write_to(folder)
    for name, relative, view, lights in DEBIAN_MODELS:
        g = debian_model(name, relative, view, lights)
        if g is not None:
            written[name] = write_debian_model(g, folder)
    return written


def main(argv):
    if len(argv) != 2:
        sys.exit(__doc__)
    out = pathlib.Path(argv[1])
    if out.exists():
        shutil.rmtree(out)
    for name, path in write_all(out).items():
        print(f"{name}: {path}")


if __name__ == "__main__":
    main(sys.argv)
