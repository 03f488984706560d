"""The files a scene file references, found the way the coordinator will look for them.

A tcfarm JSON scene names OBJ mesh files in its shapes' and shared meshes' "file"; an OBJ
scene names its material libraries with mtllib; a .gltf or .glb names its buffers and images
by "uri" (data URIs travel inside it; a .glb's own buffer is its BIN chunk). Each reference is a path relative to the scene's folder;
the farm lays the uploaded files out under exactly those paths, so they are written here
in the canonical form the API accepts ("meshes/a.obj", never "./meshes//a.obj").
"""
import json
import pathlib
import posixpath
import re
import struct
from urllib.parse import unquote


class SceneFileError(Exception):
    """A scene file that cannot be read, or that names a file it cannot have."""


class NotItsFormat(SceneFileError):
    """A file that does not read as the format its name says (an HTML page named .glb): the
    farm can say what it is instead. path: that file."""

    def __init__(self, path, message):
        super().__init__(message)
        self.path = pathlib.Path(path)


class SceneFiles:
    """scene: the parsed JSON scene, or None for a scene sent as a file (scene_file, its
    name among the assets); assets: {relative path: local file} to upload."""

    def __init__(self, scene, scene_file, assets):
        self.scene, self.scene_file, self.assets = scene, scene_file, assets


# The textures of a material's "pbr" block (glTF's model), as proto/scene.schema.json names them.
PBR_TEXTURES = ("base_color_texture", "metallic_roughness_texture", "normal_texture", "occlusion_texture",
                "emissive_texture")

def _canonical(name, scene_path, what):
    relative = posixpath.normpath(name) if name else ""
    if (not name or name.startswith("/") or "\\" in name or relative == "."
            or relative == ".." or relative.startswith("../")):
        raise SceneFileError(f"{scene_path}: {what} {name!r} is not a relative path inside the "
                             "scene's folder")
    return relative


def _add(assets, folder, name, scene_path, what):
    relative = _canonical(name, scene_path, what)
    local = folder / relative
    if not local.is_file():
        raise SceneFileError(f"{scene_path}: cannot read {what} {name!r} (looked for {local})")
    assets[relative] = local
    return relative


def _json_references(scene):
    """The mesh files and texture images a tcfarm JSON scene names."""
    shapes = scene.get("shapes") if isinstance(scene, dict) else None
    meshes = scene.get("meshes") if isinstance(scene, dict) else None
    for mesh in (shapes if isinstance(shapes, list) else []) + list(
            meshes.values() if isinstance(meshes, dict) else []):
        if isinstance(mesh, dict) and isinstance(mesh.get("file"), str):
            yield mesh["file"], "mesh file"
    materials = scene.get("materials") if isinstance(scene, dict) else None
    for material in materials.values() if isinstance(materials, dict) else []:
        if not isinstance(material, dict):
            continue
        pbr = material.get("pbr") if isinstance(material.get("pbr"), dict) else {}
        textures = [material.get("diffuse_texture")] + [pbr.get(key) for key in PBR_TEXTURES]
        for texture in textures:
            if isinstance(texture, dict) and isinstance(texture.get("image"), str):
                yield texture["image"], "texture image"


def _obj_libraries(text):
    """mtllib names, in order; a line may name several."""
    for line in text.splitlines():
        words = line.split("#", 1)[0].split()
        if words and words[0] == "mtllib":
            yield from words[1:]


# A '%' that does not start an escape of two hex digits: the farm refuses such a uri.
_MALFORMED_ESCAPE = re.compile(r"%(?![0-9A-Fa-f]{2})")


def _gltf_uris(document, path):
    """The external buffers and images a glTF document names (URI-encoded paths)."""
    for kind, what in (("buffers", "buffer"), ("images", "image")):
        entries = document.get(kind) if isinstance(document, dict) else None
        for entry in entries if isinstance(entries, list) else []:
            uri = entry.get("uri") if isinstance(entry, dict) else None
            if isinstance(uri, str) and not uri.startswith("data:"):
                if _MALFORMED_ESCAPE.search(uri):
                    raise SceneFileError(f"{path}: {what} uri {uri!r} has a '%' that is not an escape "
                                         "(a file named with '%' is written %25)")
                yield unquote(uri), what


def _glb_json(data, path):
    """A GLB's JSON chunk (the first, right after the 12-byte header)."""
    if len(data) < 20 or data[:4] != b"glTF":
        raise NotItsFormat(path, f"{path} is not a GLB file")
    length, kind = struct.unpack_from("<I4s", data, 12)
    if kind != b"JSON" or 20 + length > len(data):
        raise NotItsFormat(path, f"{path}: its first chunk is not JSON")
    return data[20:20 + length]


def _references_of_file(data, suffix, path):
    """The files a glTF or OBJ file names, relative to its own folder (canonical, and refused
    when they leave it: the farm resolves them inside that folder)."""
    for name, what in _named_by_file(data, suffix, path):
        yield _canonical(name, path, what), what


def _named_by_file(data, suffix, path):
    if suffix in (".gltf", ".glb"):
        try:
            document = json.loads(_glb_json(data, path) if suffix == ".glb" else data)
        except ValueError as e:
            raise NotItsFormat(path, f"{path} is not glTF JSON: {e}") from None
        yield from _gltf_uris(document, path)
    elif suffix == ".obj":
        for name in _obj_libraries(data.decode("utf-8", errors="replace")):
            yield name, "material library"


def _add_imported(assets, folder, scene, scene_path):
    """A JSON scene's imported file (its "import": {"file"}) and what that file names, each
    listed relative to the scene's folder (what it names stays inside its own)."""
    imported = scene.get("import") if isinstance(scene, dict) else None
    name = imported.get("file") if isinstance(imported, dict) else None
    if not isinstance(name, str):
        return
    relative = _add(assets, folder, name, scene_path, "imported file")
    local = assets[relative]
    base = posixpath.dirname(relative)
    for reference, what in _references_of_file(local.read_bytes(), local.suffix.lower(), local):
        _add(assets, folder, posixpath.join(base, reference) if base else reference, local, what)


def scene_files(path):
    """The scene at path and the files it references, ready for upload and submission."""
    path = pathlib.Path(path)
    folder = path.parent
    try:
        data = path.read_bytes()
    except OSError as e:
        raise SceneFileError(f"cannot read scene {path}: {e.strerror}") from None
    if path.suffix.lower() == ".json":
        try:
            scene = json.loads(data)
        except ValueError as e:
            raise NotItsFormat(path, f"{path} is not JSON: {e}") from None
        assets = {}
        for name, what in _json_references(scene):
            _add(assets, folder, name, path, what)
        _add_imported(assets, folder, scene, path)
        return SceneFiles(scene, None, assets)
    # Any other file goes to the farm as it is, which imports it by its type.
    assets = {path.name: path}
    for name, what in _references_of_file(data, path.suffix.lower(), path):
        _add(assets, folder, name, path, what)
    return SceneFiles(None, path.name, assets)
