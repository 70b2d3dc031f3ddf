"""Extracts the endocast of every scan in a folder and plots their ECVs (a bar per specimen).

    PYTHONPATH=build/python python3 examples/python/ecv_batch.py SCANS/ ecv.png [--iso 350]
    PYTHONPATH=build/python python3 examples/python/ecv_batch.py --phantoms ecv.png

SCANS/ holds .nrrd, .nhdr, .nii, .nii.gz, .mha or .mhd files, or one folder per DICOM series.
--phantoms runs on three generated skulls instead and prints their errors against the truth.
Writes ecv.png and ecv.csv (specimen, ecv_ml, bone_contact, warnings).
"""
import argparse
import csv
import pathlib

import matplotlib

matplotlib.use("Agg")  # no display needed
import matplotlib.pyplot as plt

import endocast

SUFFIXES = (".nrrd", ".nhdr", ".nii", ".nii.gz", ".mha", ".mhd")


def scans(folder):
    for p in sorted(pathlib.Path(folder).iterdir()):
        if p.is_dir() or p.name.endswith(SUFFIXES):
            yield p.name.split(".")[0], p


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder", nargs="?", help="folder of scans")
    ap.add_argument("plot", help="PNG to write (and a .csv beside it)")
    ap.add_argument("--iso", type=float, help="bone isovalue (default: automatic)")
    ap.add_argument("--phantoms", action="store_true", help="three generated skulls instead of a folder")
    args = ap.parse_args()
    if args.phantoms:
        spacing = {"human": 2.0, "macaque": 0.7, "mouse": 0.14}  # mm: ~20 voxels across each cavity's depth
        specimens = [(p, endocast.phantom(p, spacing=s)) for p, s in spacing.items()]
    elif args.folder:
        specimens = list(scans(args.folder))
    else:
        ap.error("give a folder of scans or --phantoms")

    rows = []
    for name, source in specimens:
        r = endocast.extract(source, iso=args.iso)
        rows.append((name, r.ecv_ml, r.report["bone_contact"], "; ".join(r.warnings)))
        truth = getattr(source, "true_ecv_ml", None)
        print(f"{name}: ECV {r.ecv_ml:.3f} mL, bone contact {r.report['bone_contact']:.2f}"
              + (f", truth {truth:.3f} mL ({100 * (r.ecv_ml / truth - 1):+.2f} %)" if truth else ""))

    out = pathlib.Path(args.plot)
    with open(out.with_suffix(".csv"), "w", newline="") as f:
        csv.writer(f).writerows([("specimen", "ecv_ml", "bone_contact", "warnings"), *rows])
    fig, ax = plt.subplots(figsize=(max(4, 0.6 * len(rows)), 3.5))
    ax.bar([r[0] for r in rows], [r[1] for r in rows], color=["tab:red" if r[3] else "tab:blue" for r in rows])
    ax.set_yscale("log" if max(r[1] for r in rows) > 20 * min(r[1] for r in rows) else "linear")
    ax.set_ylabel("ECV (mL)")
    ax.set_title("ECV (red: the run warned)")
    ax.tick_params(axis="x", rotation=45)
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    print(f"wrote {out} and {out.with_suffix('.csv')}")


if __name__ == "__main__":
    main()
