// libFuzzer target for our mesh readers (libmeshpost/src/io/). Built once per format with
// FUZZ_MESH_EXT set to ".stl", ".ply", ".obj" or ".off" (see tests/fuzz/CMakeLists.txt).
// The input bytes are parsed from memory with meshpost::read_mesh_from_memory (the same parser
// read_mesh uses). MeshIoError is the expected rejection; anything else (crash, sanitizer report,
// leak, other exception, or a result breaking read_mesh's documented guarantees) is a finding.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "meshpost/io.h"

#ifndef FUZZ_MESH_EXT
#error "FUZZ_MESH_EXT must be defined"
#endif

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::string bytes(reinterpret_cast<const char*>(data), size);
    meshpost::TriangleMesh mesh;
    try {
        mesh = meshpost::read_mesh_from_memory(bytes, FUZZ_MESH_EXT);
    } catch (const meshpost::MeshIoError&) {
        return 0;  // rejected input: expected
    }
    // Guarantees of read_mesh (io.h): indices in range, finite coordinates.
    for (const auto& f : mesh.faces)
        for (uint32_t v : f)
            if (v >= mesh.vertices.size()) {
                std::fprintf(stderr, "finding: face index %u >= %zu vertices\n", v, mesh.vertices.size());
                std::abort();
            }
    for (const auto& p : mesh.vertices)
        for (double c : p)
            if (!std::isfinite(c)) {
                std::fprintf(stderr, "finding: non-finite coordinate accepted\n");
                std::abort();
            }
    return 0;
}
