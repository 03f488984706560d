// Files a scene refers to (meshes, material libraries, later glTF buffers and textures):
// resolved only inside the scene's folder, read whole.
#pragma once

#include <filesystem>
#include <string>

namespace tcfarm {

// Resolves `name`, as the scene wrote it, inside `folder`. Throws SceneError at `pointer`
// when it is empty or absolute, cannot be resolved, or resolves (after "..", and symlinks
// that exist) outside the folder. `what` names the file's role in messages ("mesh file").
std::filesystem::path ResolveInsideFolder(const std::filesystem::path& folder, const std::string& name,
                                          const std::string& pointer, const std::string& what);

// The whole file, or SceneError at `pointer` ("cannot read <what> <name>; expected <expected>").
std::string ReadSceneFile(const std::filesystem::path& path, const std::string& name, const std::string& pointer,
                          const std::string& what, const std::string& expected);

}  // namespace tcfarm
