// The JSON types of a glTF file's properties, checked before tinygltf reads it: tinygltf
// passes over a property of the wrong type as if it were absent.
#pragma once

#include <string>
#include <utility>

#include <nlohmann/json.hpp>

namespace tcfarm::gltf {

// The first property of the wrong JSON type under `value` (an object of `schema`, "root"
// for the document), as {pointer, expected}; empty when all are right.
std::pair<std::string, std::string> WrongType(const nlohmann::json& value, const std::string& schema,
                                              const std::string& pointer);

// The JSON pointer of element `index` of a top-level collection ("/nodes/3").
std::string Pointer(const std::string& collection, size_t index);

}  // namespace tcfarm::gltf
