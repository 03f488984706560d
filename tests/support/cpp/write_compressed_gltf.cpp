// write_compressed_gltf RINGS SEGMENTS FOLDER: the sphere of compressed_gltf.h as
// plain.gltf, draco.gltf (lossless, sequential), draco_edgebreaker.gltf (14-bit positions)
// and meshopt.gltf, for tests/gltf's render comparison and tests/bench/gltf_import.sh.
#include <fstream>
#include <iostream>

#include "tests/support/cpp/compressed_gltf.h"

int main(int argc, char** argv) {
  using namespace tcfarm::compressed_gltf;
  if (argc != 4) {
    std::cerr << "usage: write_compressed_gltf RINGS SEGMENTS FOLDER\n";
    return 2;
  }
  const Sphere sphere = MakeSphere(std::stoi(argv[1]), std::stoi(argv[2]));
  const std::string folder = argv[3];
  const auto write = [&](const std::string& name, const nlohmann::json& gltf) {
    std::ofstream(folder + "/" + name) << gltf.dump();
  };
  write("plain.gltf", PlainGltf(sphere));
  write("draco.gltf", DracoGltf(sphere));
  write("draco_edgebreaker.gltf", DracoGltf(sphere, DracoOptions{false, 14}));
  write("meshopt.gltf", MeshoptGltf(sphere));
  return 0;
}
