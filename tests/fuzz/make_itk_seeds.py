#!/usr/bin/env python3
"""Writes the seed corpora of fuzz_nrrd, fuzz_nifti and fuzz_mhd (tests/fuzz/corpus/<target>/):
small valid volumes (4 x 4 x 3 voxels) in each format, raw and compressed, attached and detached
(the fuzz target writes a 4096-byte "data.raw" beside each input, see fuzz_itk.cpp). Each seed is
far below the 4096 bytes of fuzz.sh's -max_len. Run from anywhere; the files are rewritten.
"""
import gzip
import os
import struct
import zlib

HERE = os.path.dirname(os.path.abspath(__file__))
NX, NY, NZ = 4, 4, 3
N = NX * NY * NZ


def voxels(fmt):
    """N voxels packed little-endian with struct code `fmt` ('H', 'h', 'B', 'f')."""
    return struct.pack("<%d%s" % (N, fmt), *[(i * 37) % 200 for i in range(N)])


def write(target, name, data):
    d = os.path.join(HERE, "corpus", target)
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, name), "wb") as f:
        f.write(data)


def nrrd(type_name, fmt, encoding="raw", extra=""):
    data = voxels(fmt)
    if encoding == "gzip":
        payload = gzip.compress(data, mtime=0)
    elif encoding == "ascii":
        payload = " ".join(str(v) for v in struct.unpack("<%d%s" % (N, fmt), data)).encode() + b"\n"
    else:
        payload = data
    header = ("NRRD0004\ntype: %s\ndimension: 3\nspace: left-posterior-superior\n"
              "sizes: %d %d %d\nspace directions: (1,0,0) (0,1,0) (0,0,2)\n"
              "kinds: domain domain domain\nendian: little\nencoding: %s\n"
              "space origin: (0,0,0)\n%s" % (type_name, NX, NY, NZ, encoding, extra))
    if "data file:" in extra:
        return (header + "\n").encode()
    return (header + "\n").encode() + payload


def nifti(datatype, bitpix, fmt, qform=1, sform=0):
    h = bytearray(348)
    struct.pack_into("<i", h, 0, 348)
    struct.pack_into("<8h", h, 40, 3, NX, NY, NZ, 1, 1, 1, 1)
    struct.pack_into("<hh", h, 70, datatype, bitpix)
    struct.pack_into("<8f", h, 76, 1.0, 1.0, 1.0, 2.0, 1.0, 1.0, 1.0, 1.0)
    struct.pack_into("<fff", h, 108, 352.0, 1.0, 0.0)  # vox_offset, scl_slope, scl_inter
    h[123] = 2  # xyzt_units: mm
    struct.pack_into("<hh", h, 252, qform, sform)
    struct.pack_into("<6f", h, 256, 0, 0, 0, -1.5, 2.0, 0.5)  # quatern_b..d, qoffset_x..z
    struct.pack_into("<12f", h, 280, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 2, 0)  # srow_x, y, z
    h[344:348] = b"n+1\0"
    return bytes(h) + b"\0\0\0\0" + voxels(fmt)


def mha(element_type, fmt, compressed=False, data_file="LOCAL"):
    data = voxels(fmt)
    extra = ""
    if compressed:
        data = zlib.compress(data)
        extra = "CompressedDataSize = %d\n" % len(data)
    header = ("ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n"
              "CompressedData = %s\n%sTransformMatrix = 1 0 0 0 1 0 0 0 1\nOffset = 0 0 0\n"
              "ElementSpacing = 1 1 2\nDimSize = %d %d %d\nElementType = %s\nElementDataFile = %s\n"
              % ("True" if compressed else "False", extra, NX, NY, NZ, element_type, data_file))
    return header.encode() + (data if data_file == "LOCAL" else b"")


write("fuzz_nrrd", "uint16_raw.nrrd", nrrd("uint16", "H"))
write("fuzz_nrrd", "int16_gzip.nrrd", nrrd("int16", "h", "gzip"))
write("fuzz_nrrd", "uint8_ascii.nrrd", nrrd("uint8", "B", "ascii"))
write("fuzz_nrrd", "float_raw.nrrd", nrrd("float", "f"))
write("fuzz_nrrd", "detached.nhdr", nrrd("uint16", "H", extra="data file: data.raw\nbyte skip: -1\n"))

write("fuzz_nifti", "uint16_qform.nii", nifti(512, 16, "H"))
write("fuzz_nifti", "int16_sform.nii", nifti(4, 16, "h", qform=0, sform=1))
write("fuzz_nifti", "float32_noxform.nii", nifti(16, 32, "f", qform=0, sform=0))
write("fuzz_nifti", "uint8.nii", nifti(2, 8, "B"))

write("fuzz_mhd", "uint16.mha", mha("MET_USHORT", "H"))
write("fuzz_mhd", "int16_zlib.mha", mha("MET_SHORT", "h", compressed=True))
write("fuzz_mhd", "float.mha", mha("MET_FLOAT", "f"))
write("fuzz_mhd", "detached.mhd", mha("MET_UCHAR", "B", data_file="data.raw"))
