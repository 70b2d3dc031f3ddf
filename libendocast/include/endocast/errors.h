#pragma once
// The exception hierarchy of endocast. Every message names the file or parameter,
// the value found and what was expected.
#include <map>
#include <stdexcept>
#include <string>

namespace endocast {

/// A finding of a run that finished: its result stands, but a careful user should look.
struct Warning {
    std::string code;     ///< stable identifier, e.g. "bone_contact_low" (docs/report.schema.json)
    std::string message;  ///< what was found and what to do, naming the values
    std::map<std::string, double> values;  ///< the numbers it is about (units in the names: _mm, _ml)
};

/// Base of all endocast errors.
class Error : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

/// A file could not be read or written, or its content is malformed.
class IoError : public Error {
public:
    using Error::Error;
};

/// A parameter is out of range or inconsistent with the input.
class InvalidParameter : public Error {
public:
    using Error::Error;
};

/// The input is valid but the method cannot produce a result (no bone, no cavity, ...).
class NoResult : public Error {
public:
    using Error::Error;
};

/// The work would need more memory than is available or allowed; thrown before allocating.
class OutOfMemory : public Error {
public:
    using Error::Error;
};

}  // namespace endocast
