"""The files a scene file references, found the way the coordinator will look for them.

A tcfarm JSON scene names OBJ mesh files in its shapes' "file"; an OBJ scene names its
material libraries with mtllib; a .gltf names its buffers and images by "uri" (data URIs
travel inside it; a .glb carries its own). Each reference is a path relative to the scene's folder;
the farm lays the uploaded files out under exactly those paths, so they are written here
in the canonical form the API accepts ("meshes/a.obj", never "./meshes//a.obj").
"""
import json
import pathlib
import posixpath


class SceneFileError(Exception):
    """A scene file that cannot be read, or that names a file it cannot have."""


class SceneFiles:
    """scene: the parsed JSON scene, or None for a scene sent as a file (scene_file, its
    name among the assets); assets: {relative path: local file} to upload."""

    def __init__(self, scene, scene_file, assets):
        self.scene, self.scene_file, self.assets = scene, scene_file, assets


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
    for shape in shapes if isinstance(shapes, list) else []:
        if isinstance(shape, dict) and isinstance(shape.get("file"), str):
            yield shape["file"], "mesh file"
    materials = scene.get("materials") if isinstance(scene, dict) else None
    for material in materials.values() if isinstance(materials, dict) else []:
        texture = material.get("diffuse_texture") if isinstance(material, dict) else None
        if isinstance(texture, dict) and isinstance(texture.get("image"), str):
            yield texture["image"], "texture image"


def _obj_libraries(text):
    """mtllib names, in order; a line may name several."""
    for line in text.splitlines():
        words = line.split("#", 1)[0].split()
        if words and words[0] == "mtllib":
            yield from words[1:]


def _gltf_uris(document):
    """The external buffers and images a glTF document names (URI-encoded paths)."""
    from urllib.parse import unquote
    for kind, what in (("buffers", "buffer"), ("images", "image")):
        entries = document.get(kind) if isinstance(document, dict) else None
        for entry in entries if isinstance(entries, list) else []:
            uri = entry.get("uri") if isinstance(entry, dict) else None
            if isinstance(uri, str) and not uri.startswith("data:"):
                yield unquote(uri), what


def _references_of_file(data, suffix, path):
    """The files a glTF or OBJ file names, relative to its own folder."""
    if suffix == ".gltf":
        try:
            document = json.loads(data)
        except ValueError as e:
            raise SceneFileError(f"{path} is not glTF JSON: {e}") from None
        yield from _gltf_uris(document)
    elif suffix == ".obj":
        for name in _obj_libraries(data.decode("utf-8", errors="replace")):
            yield name, "material library"


def _add_imported(assets, folder, scene, scene_path):
    """A JSON scene's imported file (its "import": {"file"}) and what that file names, each
    relative to the scene's folder."""
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
            raise SceneFileError(f"{path} is not JSON: {e}") from None
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
