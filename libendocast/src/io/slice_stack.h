#pragma once
// The slices of a CT series as the scanner placed them: gantry tilt and mixed slice spacing.
//
// A DICOM series is a stack of 2-D slices, each with its ImagePositionPatient p_k (the centre of
// its first pixel, mm) and one ImageOrientationPatient (row direction r, column direction c; the
// slice normal n = r x c). Readers that stack the slices along n with one step as spacing assume
// that p_k - p_0 is parallel to n and that the steps are equal. Scanners break both:
//  - gantry tilt: the slices lean (n is not the table axis) but the positions step along the
//    table: p_k - p_0 has a component in the slice plane, the grid is sheared. Stacked along n the
//    head is distorted and volumes grow by 1/cos(tilt) (+5.5 % at 18.5 deg).
//  - mixed spacing: two or more stacks of different slice spacing in one series (4 mm slices over
//    the skull base, 7 mm above it).
// analyze_slice_stack measures both from the positions; resample_slice_stack puts the slices onto
// a regular grid in patient space (axes r, c, n; in-plane spacing kept; one slice spacing), by
// bilinear interpolation in each slice at its own in-plane offset and linear interpolation along
// n between the two nearest slices, as dcm2niix and 3D Slicer do. Distances on the result are true
// millimetres, and a mesh from it lies where the anatomy is in patient (LPS) coordinates.
#include <cstddef>
#include <string>
#include <vector>

#include "endocast/volume.h"

namespace endocast {

/// A run of slices with (almost) the same step along the normal.
struct SliceRun {
    size_t first = 0;     ///< index of its first slice (in stack order)
    size_t slices = 0;    ///< slices in the run (>= 2)
    double step_mm = 0;   ///< mean step along the normal
};

struct SliceStack {
    std::vector<double> along_mm;  ///< each slice's position along the normal, from the first (ascending)
    double tilt_deg = 0;           ///< angle between the stack's axis (first to last position) and the normal
    double shear_mm = 0;           ///< largest in-plane offset of a slice from the first (mm)
    bool tilted = false;           ///< shear_mm above a tenth of the smallest in-plane pixel
    bool regular = true;           ///< every slice within a fifth of a step of a regular grid
    std::vector<SliceRun> runs;    ///< maximal runs of equal steps (within 5 %), in order
    double min_run_step_mm = 0;    ///< the smallest step of a run of >= 2 equal steps (or of all)
    /// Where the spacing changes, for a warning: "slices 14-15: 1.08 mm (4 mm before, 7 mm after)".
    std::vector<std::string> changes;
    /// True when the stack needs resample_slice_stack (tilted or not regular).
    bool needs_resampling() const { return tilted || !regular; }
};

/// Measures the stack of slices at `positions` (ImagePositionPatient of each slice, in the order
/// they are stored in the volume) with in-plane axes `row_dir`, `col_dir` (unit) and in-plane
/// pixel spacing `pixel_mm` (the smaller of the two). Throws IoError naming `what` and the slices
/// for a duplicated slice (two at the same place), slices out of order along the normal, or a real
/// gap: a step 1.5 or more times the steps on both sides of it that agree with each other (a
/// missing slice inside a stack of regular spacing; at either end of the stack, a step that is
/// close to a whole multiple >= 2 of its neighbour). `files`, when as many as positions, names the
/// slices in messages.
SliceStack analyze_slice_stack(const std::vector<Vec3>& positions, const Vec3& row_dir, const Vec3& col_dir,
                               double pixel_mm, const std::string& what,
                               const std::vector<std::string>& files = {});

struct SliceResampling {
    double slice_spacing_mm = 0;  ///< <= 0: the stack's min_run_step_mm
    float outside = 0;            ///< value of voxels no slice covers
};

/// The grid resample_slice_stack puts `g`'s slices on (to check its size before it is allocated).
Geometry resampled_geometry(const Geometry& g, const std::vector<Vec3>& positions, const SliceStack& stack,
                            const SliceResampling& p = {});

/// `v`: the slices as read (x, y in-plane with v's spacing[0], spacing[1]; z = stack order),
/// `positions` their ImagePositionPatient, `v`'s direction columns 0 and 1 the row and column
/// directions. Returns the regular grid: direction (r, c, n), the in-plane spacing kept, slices
/// `slice_spacing_mm` apart from the first slice's plane to the last's, in-plane extent the union
/// of the slices' footprints (a tilted stack is wider along c by the shear). Deterministic and
/// parallel over output slices. Throws InvalidParameter for a spacing that is not finite, or
/// IoError when positions and slices disagree.
Volume<float> resample_slice_stack(const Volume<float>& v, const std::vector<Vec3>& positions,
                                   const SliceStack& stack, const SliceResampling& p = {});

}  // namespace endocast
