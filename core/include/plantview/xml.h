// plantview/xml.h: the plantview XML format, a whole parametric plant model as text.
//
// The network-neutral form of a model (Su et al. section 4.2): only parameters and topology
// travel, never triangles. A document holds objects; each object its primitives' parameters and
// placements, its engineering attributes and its piping topology (model.h). The schema, element
// by element, is docs/xml-format.md.
//
// Round trip
//   Reading what the writer wrote gives back every Object field for field, every float and double
//   bit for bit (negative zero and subnormals included) and every string byte for byte, whatever
//   bytes it holds (text that is not UTF-8 is percent-escaped in an element marked
//   encoding="bytes"). The one field not stored is FacetGroup::triangles: the reader calls
//   triangulate() on every facet group it reads.
//
// What the writer refuses (an error naming the object and field, nothing written for it):
//   a non-finite number, an object id of 0 (0 means "none"), an object_class outside the enum,
//   a facet group whose contour_ends or polygon_ends do not partition its vertices and contours. The reader rejects the same things,
//   so everything the writer accepts can be read back.
//
// Memory
//   The writer writes object by object. The reader hands each object to the sink as soon as its
//   closing tag has been read and checked, so its memory is bounded by the largest object (plus
//   some 50 bytes per object read, to find duplicate ids), not by the file.
//
// Errors
//   Every byte of input is untrusted: malformed or hostile input never crashes and ends in one
//   XmlError. Its message is complete on its own and names the source, the line, the element and
//   the attribute at fault, e.g.
//     plant.xml:14: <primitive kind="cylinder">: radius_m: not a number: "abc"
//     plant.xml:220: unexpected end of file: <plantview> (line 2) is not closed
//   Objects handed to the sink before an error stay valid; a reader that failed stays failed.
//   The reader does not check that pipeline_id and branch member ids name objects of the file
//   (an exported part of a plant may refer to objects outside it).
//
// Threads: a writer or reader is used by one thread at a time; different ones are independent.
#pragma once

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <string_view>

#include "plantview/model.h"

namespace plantview {

// The version written in <plantview format_version="...">. The reader accepts exactly this one.
inline constexpr int kXmlFormatVersion = 1;

struct XmlError {
  std::string message;  // complete, as described above
  uint64_t line = 0;    // 1-based line of the fault; 0 when the fault is not in the text
                        // (a file that cannot be opened or written, an object the writer refuses)
};

// ---------------------------------------------------------------------------------------------
// Writing.

// A document as text, in pieces, for callers that send it as they make it (a web service):
// the header, then any number of objects, then the footer. append_xml_object appends nothing and
// returns false with `error` set when it refuses the object (see above).
void append_xml_header(std::string& out);
bool append_xml_object(std::string& out, const Object& object, XmlError& error);
void append_xml_footer(std::string& out);

// A whole document. On failure `out` holds no complete document.
bool write_xml(std::span<const Object> objects, std::string& out, XmlError& error);

// Streams a document to a file, object by object, with a bounded buffer.
//   XmlWriter writer;
//   if (!writer.open(path, error)) ...;
//   for (...) writer.write_object(object);
//   if (!writer.close(error)) ...;   // the one check that is needed
// The first failure (a refused object or an I/O error) is kept: later write_object calls do
// nothing and close() reports it, leaving the file without its closing tag, so that no reader
// takes it for a whole model. Destroying an open writer closes the file the same way, unreported.
class XmlWriter {
 public:
  XmlWriter() = default;
  ~XmlWriter();
  XmlWriter(const XmlWriter&) = delete;
  XmlWriter& operator=(const XmlWriter&) = delete;

  // Creates (or truncates) the file and writes the header. The writer must not be open.
  bool open(const std::filesystem::path& path, XmlError& error);
  // Returns false if this object was refused, writing failed, or the writer had failed before.
  // Must be open.
  bool write_object(const Object& object);
  // Writes the footer and closes the file. Returns the first failure, if any. Must be open.
  bool close(XmlError& error);

  bool is_open() const { return file_ != nullptr; }

 private:
  bool flush();

  std::FILE* file_ = nullptr;
  std::string path_;
  std::string buffer_;
  XmlError failure_;
  bool failed_ = false;
};

// ---------------------------------------------------------------------------------------------
// Reading.

// Receives each object of a document in file order. It must not call back into the reader that
// calls it. If it throws, the exception leaves the reader, which must not be used again.
using XmlObjectSink = std::function<void(Object&&)>;

// Incremental reader: feed it the bytes of one document in pieces of any size (as they come off
// a disk or a socket), then call finish(). Pieces of any size give the same objects and the same
// error. Time is linear in the input, except for FacetGroup::triangulate(), which is quadratic in
// a polygon's vertex count at worst (a hostile 400 KB contour takes seconds).
class XmlReader {
 public:
  // `source_name` (a path, a URL) starts every error message.
  XmlReader(std::string source_name, XmlObjectSink sink);
  ~XmlReader();
  XmlReader(const XmlReader&) = delete;
  XmlReader& operator=(const XmlReader&) = delete;

  // Returns false once the document is known to be malformed; the same error is returned by
  // every later call. Must not be called after finish().
  bool feed(std::string_view bytes, XmlError& error);
  // Declares the end of the input: fails unless the root element was closed. Call once.
  bool finish(XmlError& error);

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

// A whole document held in memory (tests, fuzzing, a received message).
bool read_xml(std::string_view text, std::string_view source_name, const XmlObjectSink& sink,
              XmlError& error);

// A file, read in blocks. Errors name the path as given.
bool read_xml_file(const std::filesystem::path& path, const XmlObjectSink& sink, XmlError& error);

}  // namespace plantview
