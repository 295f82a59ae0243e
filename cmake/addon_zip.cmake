# The add-on packages, one set of sources for every Blender from 3.4 to 5.x:
#   dist/schnee_probes-<version>.zip   legacy add-on (bl_info; Blender 3.4-4.1, also installable in
#                                      4.2+ as a legacy add-on): the folder schnee_probes/.
#   build/extension/                   the same files plus blender_manifest.toml at the top: the
#                                      source of the Blender 4.2+ extension package, which Blender's
#                                      own `blender --command extension build` turns into
#                                      dist/schnee_probes-<version>-extension.zip (target
#                                      schnee_extension, scripts/build_extension.sh).
# Both hold the Python package, bake.py (the headless entry), the compiled module and, in lib/,
# every shared library the module needs that a stock Linux system lacks (Embree, TBB, qhull: the ldd
# closure of the module and of its Embree minus glibc, libstdc++ and libgcc), their RUNPATH set to
# $ORIGIN.
# <version> is bl_info["version"] of addon/schnee_probes/__init__.py.
#
# Included from the top-level CMakeLists (target schnee_addon_zip, part of ALL), and also run as a
# script (cmake -P) by that target to stage the files and write the zip.

if(CMAKE_SCRIPT_MODE_FILE)
  # Script mode. Inputs: SRC_DIR (addon/schnee_probes), MODULE (the built .so), BAKE_PY, MANIFEST
  # (configured blender_manifest.toml), STAGE (scratch folder), EXT_DIR (extension source folder),
  # ZIP (output path), PATCHELF.
  file(REMOVE_RECURSE "${STAGE}")
  file(MAKE_DIRECTORY "${STAGE}/schnee_probes/lib")
  file(GLOB_RECURSE _files RELATIVE "${SRC_DIR}" "${SRC_DIR}/*")
  foreach(_f IN LISTS _files)
    # Compiled leftovers and any module built in the source tree are not packaged; MODULE is.
    if(_f MATCHES "(^|/)__pycache__/" OR _f MATCHES "\\.(pyc|pyo|so)$" OR _f MATCHES "(^|/)\\."
       OR _f MATCHES "^lib/")
      continue()
    endif()
    get_filename_component(_dir "${_f}" DIRECTORY)
    file(COPY "${SRC_DIR}/${_f}" DESTINATION "${STAGE}/schnee_probes/${_dir}")
  endforeach()
  file(COPY "${MODULE}" DESTINATION "${STAGE}/schnee_probes")
  file(COPY "${BAKE_PY}" DESTINATION "${STAGE}/schnee_probes")

  # The shared-library closure of the module and of the Embree it opens at import (EMBREE, through
  # dlopen: pb_embree_dyn.c), minus what every Linux system (and Blender) has.
  execute_process(COMMAND ldd "${MODULE}" OUTPUT_VARIABLE _ldd RESULT_VARIABLE _rc)
  execute_process(COMMAND ldd "${EMBREE}" OUTPUT_VARIABLE _ldd2 RESULT_VARIABLE _rc2)
  if(NOT _rc EQUAL 0 OR NOT _rc2 EQUAL 0)
    message(FATAL_ERROR "addon_zip: ldd ${MODULE} / ${EMBREE} failed")
  endif()
  file(REAL_PATH "${EMBREE}" _embree_real)
  # Its soname from the file name: libembree3.so.3 (Embree 3) or libembree4.so.4 (Embree 4).
  get_filename_component(_embree_name "${_embree_real}" NAME)
  if(NOT _embree_name MATCHES "^(libembree[0-9]+\\.so\\.[0-9]+)")
    message(FATAL_ERROR "addon_zip: unexpected Embree library name ${_embree_name}")
  endif()
  string(REPLACE "\n" ";" _ldd "${_ldd}\n${_ldd2}\n\t${CMAKE_MATCH_1} => ${_embree_real} (0)")
  set(_system "^(linux-vdso|ld-linux|libc|libm|libpthread|libdl|librt|libstdc\\+\\+|libgcc_s)[.-]")
  foreach(_line IN LISTS _ldd)
    if(_line MATCHES "^[ \t]*([^ ]+) => (/[^ ]+) \\(")
      set(_soname "${CMAKE_MATCH_1}")
      set(_real "${CMAKE_MATCH_2}")
      if(_soname MATCHES "${_system}")
        continue()
      endif()
      if(_soname MATCHES "^libpython")
        message(FATAL_ERROR "addon_zip: the module links ${_soname}; it must not (stable ABI, Blender provides Python)")
      endif()
      file(REAL_PATH "${_real}" _real)
      configure_file("${_real}" "${STAGE}/schnee_probes/lib/${_soname}" COPYONLY)
      execute_process(COMMAND "${PATCHELF}" --set-rpath "$ORIGIN" "${STAGE}/schnee_probes/lib/${_soname}"
                      RESULT_VARIABLE _rc)
      if(NOT _rc EQUAL 0)
        message(FATAL_ERROR "addon_zip: patchelf on ${_soname} failed")
      endif()
    elseif(_line MATCHES "not found")
      message(FATAL_ERROR "addon_zip: unresolved library of the module: ${_line}")
    endif()
  endforeach()

  # The extension source: the package's contents at the top, with the manifest.
  file(REMOVE_RECURSE "${EXT_DIR}")
  file(COPY "${STAGE}/schnee_probes/" DESTINATION "${EXT_DIR}")
  configure_file("${MANIFEST}" "${EXT_DIR}/blender_manifest.toml" COPYONLY)

  get_filename_component(_zip_dir "${ZIP}" DIRECTORY)
  file(MAKE_DIRECTORY "${_zip_dir}")
  file(REMOVE "${ZIP}.partial")
  execute_process(COMMAND ${CMAKE_COMMAND} -E tar cf "${ZIP}.partial" --format=zip schnee_probes
                  WORKING_DIRECTORY "${STAGE}" RESULT_VARIABLE _rc)
  if(NOT _rc EQUAL 0)
    message(FATAL_ERROR "addon_zip: writing ${ZIP} failed (${_rc})")
  endif()
  file(RENAME "${ZIP}.partial" "${ZIP}")
  return()
endif()

find_program(SCHNEE_PATCHELF patchelf REQUIRED)
set(_addon_src ${CMAKE_SOURCE_DIR}/addon/schnee_probes)
file(STRINGS ${_addon_src}/__init__.py _ver_line REGEX "\"version\"[ ]*:[ ]*\\(")
if(_ver_line MATCHES "\\(([0-9]+)[ ]*,[ ]*([0-9]+)[ ]*,[ ]*([0-9]+)")
  set(SCHNEE_ADDON_VERSION "${CMAKE_MATCH_1}.${CMAKE_MATCH_2}.${CMAKE_MATCH_3}")
else()
  set(SCHNEE_ADDON_VERSION "${PROJECT_VERSION}")
endif()
set(SCHNEE_ADDON_ZIP ${CMAKE_SOURCE_DIR}/dist/schnee_probes-${SCHNEE_ADDON_VERSION}.zip
    CACHE INTERNAL "Path of the add-on zip")

file(GLOB_RECURSE _addon_inputs CONFIGURE_DEPENDS ${_addon_src}/*.py ${_addon_src}/*.toml ${_addon_src}/*.json
     ${_addon_src}/*.js)
list(FILTER _addon_inputs EXCLUDE REGEX "/__pycache__/")

# The extension manifest, its version from bl_info (one version for both packages).
configure_file(${CMAKE_SOURCE_DIR}/cmake/blender_manifest.toml.in ${CMAKE_BINARY_DIR}/blender_manifest.toml @ONLY)
set(SCHNEE_EXTENSION_DIR ${CMAKE_BINARY_DIR}/extension CACHE INTERNAL "Extension source folder")

add_custom_command(
  OUTPUT ${SCHNEE_ADDON_ZIP}
  COMMAND ${CMAKE_COMMAND} -DSRC_DIR=${_addon_src} -DMODULE=$<TARGET_FILE:_schnee_native>
          -DBAKE_PY=${CMAKE_SOURCE_DIR}/bake.py -DMANIFEST=${CMAKE_BINARY_DIR}/blender_manifest.toml
          -DSTAGE=${CMAKE_BINARY_DIR}/addon_zip -DEXT_DIR=${SCHNEE_EXTENSION_DIR}
          -DZIP=${SCHNEE_ADDON_ZIP} -DPATCHELF=${SCHNEE_PATCHELF} -DEMBREE=$<TARGET_FILE:embree>
          -P ${CMAKE_CURRENT_LIST_FILE}
  DEPENDS _schnee_native $<TARGET_FILE:_schnee_native> ${_addon_inputs} ${CMAKE_CURRENT_LIST_FILE}
          ${CMAKE_SOURCE_DIR}/bake.py ${CMAKE_BINARY_DIR}/blender_manifest.toml
  COMMENT "Packaging the add-on: dist/schnee_probes-${SCHNEE_ADDON_VERSION}.zip"
  VERBATIM)
add_custom_target(schnee_addon_zip ALL DEPENDS ${SCHNEE_ADDON_ZIP})

# The Blender 4.2+ extension package, built and validated by Blender 4.3's own
# `blender --command extension build/validate` in a Debian 13 chroot (needs root and debootstrap the
# first time: scripts/blender-chroot.sh). Not part of ALL.
set(SCHNEE_EXTENSION_ZIP ${CMAKE_SOURCE_DIR}/dist/schnee_probes-${SCHNEE_ADDON_VERSION}-extension.zip
    CACHE INTERNAL "Path of the extension package")
add_custom_command(
  OUTPUT ${SCHNEE_EXTENSION_ZIP}
  COMMAND ${CMAKE_SOURCE_DIR}/scripts/build_extension.sh ${SCHNEE_EXTENSION_DIR} ${SCHNEE_EXTENSION_ZIP}
  DEPENDS ${SCHNEE_ADDON_ZIP} ${CMAKE_SOURCE_DIR}/scripts/build_extension.sh
  COMMENT "Building the extension with Blender: dist/schnee_probes-${SCHNEE_ADDON_VERSION}-extension.zip"
  VERBATIM)
add_custom_target(schnee_extension DEPENDS ${SCHNEE_EXTENSION_ZIP})
