#pragma once
// The truth for the shared mouse microCT scans (../shared/data/mouse-microct): the template's expert
// endocranial label (label 15) carried onto each scan by a thin-plate spline on the 45 skull
// landmarks, and the scores of an endocast against it (docs/accuracy.md, "Mouse microCT").
//
// Frames: landmarks are LPS mm (3D Slicer markups). Five of the shared landmark files lie in a
// frame near the template's, off their scan; tests/mouse/landmark_frames.json holds the rigid map
// of each such file onto its scan (found by scripts/mouse_landmark_frames.py: the template's skull
// warped into the file's frame, fitted to the scan's bone, refined on the template's intensities).
//
// Scores, all in the template's frame through the spline (scan -> template):
//  - dice: 2|A n B| / (|A| + |B|) of the result's voxels and the carried label's;
//  - ecv_error: the result's ECV (mesh) over the carried label's volume, minus 1;
//  - nasal_share: the result's volume beyond the label's anterior end (template LPS y below the
//    label's smallest), over the label's volume;
//  - fm_reach_mm: how far the result's voxels reach past the foramen magnum's plane (through
//    basion, landmark 50, and opisthion, 21, along the template's left-right axis), mm, and
//    fm_share: its volume past that plane over the label's volume.
#include <array>
#include <map>
#include <string>
#include <vector>

#include "endocast/volume.h"

namespace mouse_truth {

using endocast::Geometry;
using endocast::Vec3;
using endocast::Volume;

/// Control points of a 3D Slicer markups file (.mrk.json), by their numeric label, in LPS mm
/// (a file in RAS is converted). Throws std::runtime_error for an unreadable file.
std::map<int, Vec3> read_markups(const std::string& path);

/// A rigid map p -> R p + t (R row-major).
struct Rigid {
    std::array<double, 9> R{1, 0, 0, 0, 1, 0, 0, 0, 1};
    Vec3 t{0, 0, 0};
    Vec3 operator()(const Vec3& p) const;
};

/// The maps of landmark_frames.json by scan name (the file name without .nii.gz).
std::map<std::string, Rigid> read_frames(const std::string& path);

/// Thin-plate spline in 3D (kernel |r|, with an affine part) through matching point pairs.
class ThinPlate {
public:
    ThinPlate(const std::vector<Vec3>& from, const std::vector<Vec3>& to);
    Vec3 operator()(const Vec3& p) const;

private:
    std::vector<Vec3> from_;
    std::vector<std::array<double, 3>> w_;  // one weight per point, then the affine part (4 rows)
};

/// The template: its label volume, landmarks, and the reference geometry of the scores.
struct Template {
    Volume<float> labels;
    std::map<int, Vec3> landmarks;
    double label_mm3 = 0;      ///< volume of label 15
    double anterior_y = 0;     ///< smallest LPS y of a label-15 voxel centre (its anterior end)
    Vec3 fm_point{0, 0, 0};    ///< basion
    Vec3 fm_normal{0, 0, 0};   ///< unit, pointing away from the braincase (caudal)
};

/// Reads DIR/low_res_template_UCHAR-label.nii.gz and DIR/45_LM-skull.mrk.json.
Template load_template(const std::string& dir);

/// The label carried onto a scan's grid, and the spline from the scan to the template.
struct Carried {
    Volume<uint8_t> label;     ///< 1 = label 15, on the scan's grid
    double label_mm3 = 0;
    ThinPlate to_template;
};

/// Carries label 15 onto `scan` (its grid) through the landmarks both share (scan landmarks in
/// the scan's world frame, after its rigid frame map if any). Nearest template voxel.
Carried carry(const Template& tpl, const Geometry& scan, const std::map<int, Vec3>& scan_landmarks);

struct Scores {
    double dice = 0, ecv_error = 0, nasal_share = 0, fm_reach_mm = 0, fm_share = 0;
    double label_ml = 0, ecv_ml = 0;
};

/// The scores of a result (its mask, 1 = endocast, on the scan's grid; its ECV from the mesh).
Scores score(const Template& tpl, const Carried& truth, const Volume<uint8_t>& mask, double ecv_ml);

/// A CT made from the atlas' 35 um label map (template/35_mic_23strain_mus_template_UCHAR-label.nii.gz),
/// the expert's skull at microCT resolution: bone (labels 1, 2, 21) 1500 HU and everything else
/// 40 HU (soft tissue), block-averaged by `factor` (2: 70 um, 4: 141 um), blurred (Gaussian, sigma
/// 0.6 voxel) and with noise (sigma 20 HU, fixed seed); the truth is label 15 by majority in each
/// block (458.5 mm^3 at 35 um). Throws std::runtime_error for an unreadable file.
struct AtlasCt {
    Volume<int16_t> ct;
    Volume<uint8_t> label;
    double label_mm3 = 0;
};
AtlasCt atlas_ct(const Volume<float>& label_map, int factor);

/// Dice of two masks on one grid.
double dice(const Volume<uint8_t>& a, const Volume<uint8_t>& b);

/// The scan's landmarks in its own frame: the file's, mapped by `frames` when it lists the scan.
std::map<int, Vec3> scan_landmarks(const std::string& markups_path, const std::string& scan_name,
                                   const std::map<std::string, Rigid>& frames);

}  // namespace mouse_truth
