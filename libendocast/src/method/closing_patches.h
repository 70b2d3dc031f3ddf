#pragma once
// The closing surfaces of an endocast mesh as patches of faces (internal to the method's steps:
// dips.cpp, caps.cpp): the edge-connected patches of faces not on bone, grown by rings, and a test
// of whether a moved patch crosses the rest of the mesh.
#include <array>
#include <cstdint>
#include <vector>

#include "meshpost/mesh.h"

namespace endocast {

/// Fills a patch's holes: from each face next to it, a walk over the faces not in it that ends
/// before it has seen as many faces as the patch has is a piece it encloses (it joins the patch,
/// and so do the other patches inside it).
struct Enclosure {
    std::vector<int64_t> seen;  // the walk that last reached each face
    int64_t walk = 0;
    explicit Enclosure(size_t faces) : seen(faces, -1) {}

    void fill(std::vector<std::vector<uint32_t>>& patches, size_t id, std::vector<int64_t>& owner,
              const std::vector<std::array<uint32_t, 3>>& nb);
};

/// The edge-connected patches of faces not on bone, each with what it encloses (the pieces of the
/// rest that it alone bounds and that are smaller than it: a few faces whose sample 1 mm out hit
/// the hole's wall, and what lies inside them), in the order of their first face. patch_of (one
/// per face, -1 on entry) gets each face's patch; those enclosed by another are empty.
std::vector<std::vector<uint32_t>> off_bone_patches(const meshpost::TriangleMesh& m, const std::vector<uint8_t>& on_bone,
                                                    const std::vector<std::array<uint32_t, 3>>& nb,
                                                    std::vector<int64_t>& patch_of, Enclosure& e);

/// The patch grown by `rings` rings of faces across its edges (faces in no other patch: owner < 0;
/// they get owner `id`): the faces on bone along a hole's rounded rim, whose sample 1 mm out hit
/// the hole's wall.
void grow_patch(std::vector<uint32_t>& faces, const std::vector<std::array<uint32_t, 3>>& nb,
                std::vector<int64_t>& owner, int64_t id, int rings);

/// A face of the patch (moved) crosses another face of the mesh: every face whose box meets the
/// patch's box is tested against the patch's faces whose boxes it meets (orient3d in doubles).
bool crosses_the_mesh(const meshpost::TriangleMesh& m, const std::vector<uint32_t>& patch);

}  // namespace endocast
