# Turns the GL backend's .glsl files into a C++ header of string constants (cmake -P, run by the
# build whenever one of them changes: render/CMakeLists.txt).
#   -DSOURCE_DIR=<folder of the .glsl files> -DNAMES=<file names, comma-separated> -DOUTPUT=<header>
# Each file becomes `inline constexpr ShaderFile k<Name>{"<file>", R"glsl(<text>)glsl"}` (the
# name from the file's: surface.vert.glsl -> kSurfaceVert) in plantview::detail::shader_files,
# and kAll lists them in the order given. A file must end with a newline (the backend puts files
# one after the other into one shader) and must not hold the raw string's end, `)glsl"`.
cmake_minimum_required(VERSION 3.20)
foreach(var SOURCE_DIR NAMES OUTPUT)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "embed_shaders.cmake: -D${var}=... is missing")
  endif()
endforeach()
string(REPLACE "," ";" names "${NAMES}")

set(out "// Generated from render/src/gl/shaders/*.glsl by render/src/gl/embed_shaders.cmake: edit those.\n")
string(APPEND out "#pragma once\n\n#include <string_view>\n\nnamespace plantview::detail::shader_files {\n\n")
string(APPEND out "// A .glsl file: its name (under render/src/gl/shaders) and its text.\n")
string(APPEND out "struct ShaderFile {\n  std::string_view name;\n  std::string_view text;\n};\n\n")
set(all "")
foreach(name IN LISTS names)
  file(READ "${SOURCE_DIR}/${name}" text)
  if(text MATCHES "\\)glsl\"")
    message(FATAL_ERROR "${SOURCE_DIR}/${name}: holds `)glsl\"`, which ends the raw string it is embedded in")
  endif()
  if(NOT text MATCHES "\n$")
    message(FATAL_ERROR "${SOURCE_DIR}/${name}: does not end with a newline")
  endif()
  # surface.vert.glsl -> kSurfaceVert
  string(REGEX REPLACE "\\.glsl$" "" stem "${name}")
  string(REGEX MATCHALL "[A-Za-z0-9]+" words "${stem}")
  set(constant "k")
  foreach(word IN LISTS words)
    string(SUBSTRING "${word}" 0 1 first)
    string(SUBSTRING "${word}" 1 -1 rest)
    string(TOUPPER "${first}" first)
    string(APPEND constant "${first}${rest}")
  endforeach()
  string(APPEND out "inline constexpr ShaderFile ${constant}{\"${name}\", R\"glsl(${text})glsl\"};\n\n")
  list(APPEND all "${constant}")
endforeach()
list(JOIN all ", " all_list)
string(APPEND out "// Every file, for the checks (tests/test_shaders.cpp).\n")
string(APPEND out "inline constexpr ShaderFile kAll[] = {${all_list}};\n\n")
string(APPEND out "}  // namespace plantview::detail::shader_files\n")

# Written only when it changes, so that what includes it rebuilds only then.
if(EXISTS "${OUTPUT}")
  file(READ "${OUTPUT}" previous)
  if(previous STREQUAL out)
    return()
  endif()
endif()
file(WRITE "${OUTPUT}" "${out}")
