// The user's parameters turned into the concrete values an extraction runs with, once (pipeline.h).
#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>

#include "endocast/pipeline.h"

namespace endocast {

template <class T>
ResolvedParams resolve(const Volume<T>& ct, const ExtractParams& p) {
    ResolvedParams r;
    const Geometry& g = ct.geometry();
    if (p.binarize.isovalue) {
        if (!std::isfinite(*p.binarize.isovalue)) {
            std::ostringstream s;
            s << "isovalue " << *p.binarize.isovalue << ", expected a finite number";
            throw InvalidParameter(s.str());
        }
        r.isovalue = *p.binarize.isovalue;
        r.isovalue_rule = "given";
    } else {
        r.isovalue = automatic_isovalue(ct, &r.isovalue_rule, &r.isovalue_other, &r.isovalue_margin);
        r.isovalue_automatic = true;
    }
    if (!(p.seeds.scale > 0 && p.seeds.scale < 1)) {
        std::ostringstream s;
        s << "seed scale " << p.seeds.scale << ", expected 0 < s < 1";
        throw InvalidParameter(s.str());
    }
    if (!p.void_fill.radius_mm && (!std::isfinite(p.void_fill.radius_voxels) || p.void_fill.radius_voxels < 0))
        throw InvalidParameter("void fill radius " + std::to_string(p.void_fill.radius_voxels) +
                               " voxels, expected a finite value >= 0");
    r.smallest_spacing_mm = g.smallest_spacing();
    r.void_radius_mm = void_fill_radius_mm(p.void_fill, g);  // checked by fill_voids
    // As given when given in voxels (the same number, not mm / spacing rounded twice).
    r.void_radius_voxels = p.void_fill.radius_mm ? *p.void_fill.radius_mm / r.smallest_spacing_mm : p.void_fill.radius_voxels;
    r.thin_bone_prominence = p.binarize.thin_bone_prominence;
    r.seed_mode = p.seeds.mode;
    r.seed_scale = p.seeds.scale;
    r.surface = p.surface;
    return r;
}

template ResolvedParams resolve<float>(const Volume<float>&, const ExtractParams&);
template ResolvedParams resolve<int16_t>(const Volume<int16_t>&, const ExtractParams&);

}  // namespace endocast
