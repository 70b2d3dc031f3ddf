// TriangleMesh is a plain struct; this unit anchors the library.
#include "meshpost/mesh.h"

#include <algorithm>

namespace meshpost {

size_t first_face_with_bad_index(const TriangleMesh& m) {
    const size_t nv = m.vertices.size();
    const int64_t nf = int64_t(m.faces.size());
    int64_t first = nf;
#pragma omp parallel for schedule(static) reduction(min : first)
    for (int64_t f = 0; f < nf; ++f) {
        const Face& t = m.faces[size_t(f)];
        if (t[0] >= nv || t[1] >= nv || t[2] >= nv) first = std::min(first, f);
    }
    return size_t(first);
}

}  // namespace meshpost
