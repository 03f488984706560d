// write_compressed_gltf RINGS SEGMENTS FOLDER: the sphere of compressed_gltf.h as
// plain.gltf, draco.gltf (lossless, sequential), draco_edgebreaker.gltf (14-bit positions)
// meshopt.gltf and its plain twin in meshopt's triangle order, skinned.gltf and skinned_draco.gltf (skinned_compressed_gltf.h's bending
// sphere, lossless), and each as .glb too (buffer 0 in the BIN chunk), for tests/gltf's render
// comparison, tests/bench's import figures and scripts/fuzz's seeds.
#include <fstream>
#include <iostream>

#include "tests/support/cpp/skinned_compressed_gltf.h"

int main(int argc, char** argv) {
  using namespace tcfarm::compressed_gltf;
  if (argc != 4) {
    std::cerr << "usage: write_compressed_gltf RINGS SEGMENTS FOLDER\n";
    return 2;
  }
  const Sphere sphere = MakeSphere(std::stoi(argv[1]), std::stoi(argv[2]));
  const std::string folder = argv[3];
  const auto write = [&](const std::string& name, const nlohmann::json& gltf) {
    std::ofstream(folder + "/" + name + ".gltf") << gltf.dump();
    std::ofstream(folder + "/" + name + ".glb", std::ios::binary) << Glb(gltf);
  };
  write("plain", PlainGltf(sphere));
  write("draco", DracoGltf(sphere));
  write("draco_edgebreaker", DracoGltf(sphere, DracoOptions{false, 14}));
  write("meshopt", MeshoptGltf(sphere));
  write("meshopt_order_plain", PlainGltf(WithMeshoptIndexOrder(sphere)));
  write("skinned", SkinnedPlainGltf(sphere));
  write("skinned_draco", SkinnedDracoGltf(sphere));
  return 0;
}
