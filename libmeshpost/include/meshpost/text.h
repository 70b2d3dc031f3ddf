#pragma once
// String helpers shared by the libraries and the CLI: case, trimming, splitting, file extensions
// and the "(x, y, z)" form of a point in messages.
#include <array>
#include <string>
#include <vector>

namespace meshpost::text {

std::string lower(std::string s);  ///< ASCII lower case
std::string upper(std::string s);  ///< ASCII upper case
/// `s` without the blanks (spaces, tabs, line ends, NUL padding of DICOM values) at both ends.
std::string trim(const std::string& s);
bool ends_with(const std::string& s, const std::string& suffix);
/// The lower-case extension of the file name with its dot (".gz" for a.nii.gz), "" when the file
/// name has none (a dot in a folder name does not count).
std::string lower_extension(const std::string& path);
/// The pieces of `s` between occurrences of `sep` (one piece when there is none; empty pieces kept).
std::vector<std::string> split(const std::string& s, const std::string& sep);
/// The words of `s`, separated by any run of blanks.
std::vector<std::string> words(const std::string& s);
/// "(x, y, z)" with the stream's default precision, for messages.
std::string point(const std::array<double, 3>& v);

}  // namespace meshpost::text
