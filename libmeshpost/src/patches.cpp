// Face neighbours and edge-connected patches of faces (patches.h).
#include "meshpost/patches.h"

#include <omp.h>

#include <algorithm>
#include <string>

namespace meshpost {

VertexFaces vertex_faces(const TriangleMesh& m, const char* fn) {
    if (const size_t bad = first_face_with_bad_index(m); bad < m.faces.size())
        for (uint32_t v : m.faces[bad])
            if (v >= m.vertices.size())
                throw InvalidMesh(std::string(fn) + ": a face references vertex " + std::to_string(v) + " of " +
                                  std::to_string(m.vertices.size()));
    // A counting sort on T threads, each counting and then placing the faces of its own run of face
    // numbers (thread t's faces of a vertex after those of the threads before it: face order for
    // any T).
    const size_t nv = m.vertices.size(), nf = m.faces.size();
    const int T = std::max(1, std::min(8, omp_get_max_threads()));
    VertexFaces r;
    r.start.assign(nv + 1, 0);
    std::vector<uint32_t> cursor(size_t(T) * nv, 0);
    auto run = [&](int t, auto&& fn_of_face) {
        for (size_t f = nf * size_t(t) / size_t(T); f < nf * size_t(t + 1) / size_t(T); ++f) fn_of_face(uint32_t(f));
    };
#pragma omp parallel for schedule(static, 1) num_threads(T)
    for (int t = 0; t < T; ++t) {
        uint32_t* count = cursor.data() + size_t(t) * nv;
        run(t, [&](uint32_t f) {
            for (uint32_t v : m.faces[f]) ++count[v];
        });
    }
    for (size_t v = 0; v < nv; ++v) {
        uint32_t at = r.start[v];
        for (int t = 0; t < T; ++t) {
            const uint32_t c = cursor[size_t(t) * nv + v];
            cursor[size_t(t) * nv + v] = at;
            at += c;
        }
        r.start[v + 1] = at;
    }
    r.faces.resize(r.start.back());
#pragma omp parallel for schedule(static, 1) num_threads(T)
    for (int t = 0; t < T; ++t) {
        uint32_t* fill = cursor.data() + size_t(t) * nv;
        run(t, [&](uint32_t f) {
            for (uint32_t v : m.faces[f]) r.faces[fill[v]++] = f;
        });
    }
    return r;
}

std::vector<std::array<uint32_t, 3>> face_neighbours(const TriangleMesh& m) {
    const VertexFaces vf = vertex_faces(m, "face_neighbours");
    const std::vector<uint32_t>& start = vf.start;
    const std::vector<uint32_t>& around = vf.faces;
    std::vector<std::array<uint32_t, 3>> nb(m.faces.size(), {kNoFace, kNoFace, kNoFace});
#pragma omp parallel for schedule(static)
    for (int64_t f = 0; f < int64_t(m.faces.size()); ++f)
        for (int a = 0; a < 3; ++a) {
            const uint32_t u = m.faces[size_t(f)][a], w = m.faces[size_t(f)][(a + 1) % 3];
            for (uint32_t k = start[u]; k < start[u + 1]; ++k) {
                const uint32_t g = around[k];
                if (g == uint32_t(f)) continue;
                const Face& o = m.faces[g];
                if (o[0] == w || o[1] == w || o[2] == w) {
                    nb[size_t(f)][size_t(a)] = g;
                    break;
                }
            }
        }
    return nb;
}

std::vector<std::vector<uint32_t>> face_patches(const std::vector<std::array<uint32_t, 3>>& nb,
                                                const std::vector<uint8_t>& member) {
    if (member.size() != nb.size())
        throw InvalidMesh("face_patches: " + std::to_string(member.size()) + " flags for " +
                          std::to_string(nb.size()) + " faces");
    std::vector<uint8_t> seen(nb.size(), 0);
    std::vector<std::vector<uint32_t>> patches;
    for (uint32_t s = 0; s < nb.size(); ++s) {
        if (!member[s] || seen[s]) continue;
        std::vector<uint32_t> faces{s};
        seen[s] = 1;
        for (size_t i = 0; i < faces.size(); ++i)
            for (uint32_t g : nb[faces[i]])
                if (g != kNoFace && g < nb.size() && member[g] && !seen[g]) {
                    seen[g] = 1;
                    faces.push_back(g);
                }
        patches.push_back(std::move(faces));
    }
    return patches;
}

std::vector<uint8_t> faces_touching(const TriangleMesh& mesh, const std::vector<uint32_t>& vertices) {
    const size_t nv = mesh.vertices.size();
    std::vector<uint8_t> listed(nv, 0);
    for (uint32_t v : vertices) {
        if (v >= nv)
            throw InvalidMesh("faces_touching: vertex " + std::to_string(v) + " listed, the mesh has " +
                              std::to_string(nv) + " vertices");
        listed[v] = 1;
    }
    std::vector<uint8_t> touching(mesh.faces.size(), 0);
    const int64_t nf = int64_t(mesh.faces.size());
#pragma omp parallel for schedule(static)
    for (int64_t f = 0; f < nf; ++f)
        for (uint32_t v : mesh.faces[size_t(f)])
            if (v >= nv || listed[v]) touching[size_t(f)] = 1;
    return touching;
}

}  // namespace meshpost
