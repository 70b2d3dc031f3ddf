#pragma once
// Stage 4: seeds for the watershed, on the distance field d (mm) of the empty space.
//
// Border seeds (every mode): "other" = every empty voxel b on the faces of the volume and every
//   voxel within s*d(b) of one (s = scale < 1). The union of balls of varying radius is exact: a
//   generalized distance transform with f0(b) = -(s d(b))^2.
// SeedMode::AutoLargest (the paper's rule): "endocast" = the voxel e of largest distance outside the
//   other seeds and every voxel within s*d(e) of it.
// SeedMode::Auto (default): the cavity is chosen by enclosure, not size alone. Candidate centres are
//   the deepest local maxima of d, each outside the maximal balls of the deeper ones (up to
//   max_candidates, at least min_candidate_depth * the deepest); every candidate floods its own
//   region (one multi-label watershed). Regions joined by a shallow saddle (pass >= merge_pass *
//   the shallower depth) are one cavity when the shallower one is itself enclosed by bone
//   (>= merge_enclosure, not counting the faces it shares with other candidates' regions). Each cavity is scored by
//     enclosure^4 * volume_ml,
//   enclosure being the fraction of its boundary faces that are bone (a braincase: > 0.9; the air
//   between a CT couch and the neck: ~0.4). The best becomes "endocast", the other candidates
//   "other"; a warning is issued when the runner-up scores more than half the best. When the chosen
//   cavity is poorly enclosed (< border_retry_enclosure), or the volume border cuts a section of
//   it ringed by bone (border_retry_section_share), the border balls may have eaten into a cavity
//   cut by the volume border: it is chosen again with the border voxels alone as seeds.
// SeedMode::Distance (the paper's alternative for small braincases): components of {d >= t};
//   those touching the volume's faces are "other", the largest remaining one is "endocast".
// SeedMode::Point: "endocast" = the ball of radius s*d(p) around a given world point p (mm);
//   "other" as in Auto.
#include <array>
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "endocast/volume.h"
#include "endocast/stages/watershed.h"

namespace endocast {

enum class SeedMode { Auto, AutoLargest, Distance, Point };
std::string to_string(SeedMode m);  ///< "auto", "auto-largest", "distance", "point" (the CLI parses them)

struct SeedParams {
    SeedMode mode = SeedMode::Auto;
    double scale = 0.9;                    ///< s in (0, 1): ball radius as a fraction of d
    double distance_threshold_mm = 0;      ///< t for SeedMode::Distance (mm, > 0)
    std::vector<Vec3> points_world;        ///< SeedMode::Point: points inside the braincase (mm)
    int max_candidates = 12;               ///< SeedMode::Auto: candidate cavities examined
    double min_candidate_depth = 0.2;      ///< SeedMode::Auto: fraction of the deepest distance
    double merge_pass = 0.75;              ///< SeedMode::Auto: saddle fraction merging two regions
    double merge_enclosure = 0.6;          ///< SeedMode::Auto: own enclosure a merged region needs
    /// Scale of the border balls; < 0 = `scale`. 0 seeds only the empty face voxels: for a scan
    /// cropped through the braincase, where border balls would eat into the cavity (phantom with
    /// the base cut 15 mm up: -14% ECV with 0.9, -0.6% with 0). With 0 on every scan, the phantoms
    /// that are not cropped gain ~0.1% ECV; so by default (< 0) SeedMode::Auto uses `scale` and
    /// retries with 0 only when the chosen cavity's enclosure is below border_retry_enclosure.
    double border_scale = -1.0;
    /// SeedMode::Auto with border_scale < 0: enclosure under which the border balls are suspected
    /// of eating into a cavity cut by the volume border (values measured: docs/method/defaults.md).
    /// The retry is kept when it finds the same cavity (centres closer than its depth)
    /// not worse enclosed (border_retry_enclosure_slack); a warning says so. 0 disables.
    double border_retry_enclosure = 0.9;
    /// ... or when more than this share of its boundary faces the border balls (a ball eating a
    /// dent into a cavity that meets the border over a small area).
    double border_retry_ball_share = 0.01;
    /// The retry is kept when its enclosure is at most this much below the first one's.
    double border_retry_enclosure_slack = 0.02;
    /// The retry's warning is given only when the cavity grew by more than this share (the border
    /// balls had eaten into it); a smaller change is taken silently.
    double border_retry_warn_growth = 0.05;
    /// ... or when bone rings, within a face of the volume, an empty region at least this share
    /// of the chosen cavity's cross-section (pi r^2, r the radius of a ball of its volume): a
    /// cavity the border cuts, not a canal. Then the retry is kept also when it scores higher
    /// (enclosure^4 x volume) and is enclosed like a braincase (border_retry_min_enclosure): the
    /// border balls can leave a remnant of the cavity,
    /// or flood a pocket the border cuts from below. 0 disables.
    double border_retry_section_share = 0.15;
    double border_retry_min_enclosure = 0.6;
    /// The volume is a box of a larger scan: its voxel (0, 0, 0) is the scan's voxel `box_lo`, the
    /// scan has `scan_dims` voxels (0: the volume is the whole scan), and the scan's voxels outside
    /// the box are empty space joined to its border (the air around the skull;
    /// ExtractionResult::work_box). The border seeds are then the scan's: the balls of the scan's
    /// face voxels (their distance to bone measured through the air outside the box) as far as
    /// they reach into the box, and every empty voxel of a face of the box inside the scan (the
    /// outside flood reaches it from beyond at its own depth). Balls from a face of the box, a few
    /// mm from the skull, would reach through its openings (a foramen magnum) where the scan's
    /// own, farther away, do not.
    Dims box_lo{0, 0, 0};
    Dims scan_dims{0, 0, 0};
    /// SeedMode::Auto: keep the candidate flood, turned into the start of the watershed of the
    /// seeds chosen (SeedResult::flood), so that the watershed resumes it (resume_watershed)
    /// instead of flooding the whole volume again. For a watershed with default parameters.
    bool keep_flood = false;
};

/// A candidate cavity examined by SeedMode::Auto.
struct CavityCandidate {
    Vec3 centre_world{0, 0, 0};            ///< deepest point (mm)
    double depth_mm = 0;                   ///< distance to bone at the centre
    double volume_ml = 0;                  ///< voxels of its flooded region (merged members summed)
    double enclosure = 0;                  ///< fraction of its boundary faces that are bone
    double score = 0;                      ///< enclosure^4 * volume_ml
    int merged_into = -1;                  ///< index of the candidate it was merged with, or -1
    /// Share of its region's boundary faces toward the outside seeds' border balls inside the volume
    /// (not the border voxels themselves): a ball eating into a cavity that meets the volume border.
    double border_ball_share = 0;
    bool chosen = false;
};

struct SeedResult {
    /// Per voxel: kBone where bone, kOther / kEndocast for seeds, kUnlabelled elsewhere.
    Volume<uint8_t> labels;
    std::vector<Vec3> endocast_seeds_world;  ///< centres of the endocast seed balls (mm)
    std::vector<double> endocast_seed_radii_mm;
    double endocast_seed_distance_mm = 0;    ///< d at the (first) endocast seed centre
    size_t endocast_seed_voxels = 0;
    size_t other_seed_voxels = 0;
    std::vector<CavityCandidate> candidates;  ///< SeedMode::Auto: every candidate, deepest first
    double border_scale = 0;                 ///< scale of the border balls used
    std::vector<Warning> warnings;
    /// SeedParams::keep_flood: the candidate flood with the chosen candidates' labels made
    /// kEndocast, the others' taken away (kUnlabelled) and `labels`' seeds set (at their own
    /// levels), with its flood levels: resume_watershed(labels, levels, distance) is the watershed
    /// of `labels`. Empty when the flood's labels disagree with a seed (a rejected candidate's
    /// centre inside another's region) or it has too many levels: then flood `labels`.
    struct ResumableFlood {
        Volume<uint8_t> labels;
        FloodLevels levels;
    };
    std::optional<ResumableFlood> flood;
};

/// Places seeds. `bone` is 0/1, `distance` the distance (mm) of each voxel to the nearest bone.
/// Throws InvalidParameter (bad scale/threshold, a seed point outside the volume or in bone) or
/// NoResult (no empty voxel left for the endocast, no component above the threshold).
SeedResult place_seeds(const Volume<uint8_t>& bone, const Volume<float>& distance,
                       const SeedParams& p = {});

}  // namespace endocast
