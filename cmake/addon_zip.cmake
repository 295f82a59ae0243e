# The add-on zip: dist/schnee_probes-<version>.zip holding schnee_probes/ (the Python package and the
# compiled _schnee_native.abi3.so, no __pycache__), installable through Preferences > Add-ons >
# Install. <version> is bl_info["version"] of addon/schnee_probes/__init__.py.
#
# Included from the top-level CMakeLists (target schnee_addon_zip, part of ALL), and also run as a
# script (cmake -P) by that target to stage the files and write the zip.

if(CMAKE_SCRIPT_MODE_FILE)
  # Script mode. Inputs: SRC_DIR (addon/schnee_probes), MODULE (the built .so), STAGE (scratch
  # folder), ZIP (output path).
  file(REMOVE_RECURSE "${STAGE}")
  file(MAKE_DIRECTORY "${STAGE}/schnee_probes")
  file(GLOB_RECURSE _files RELATIVE "${SRC_DIR}" "${SRC_DIR}/*")
  foreach(_f IN LISTS _files)
    # Compiled leftovers and any module built in the source tree are not packaged; MODULE is.
    if(_f MATCHES "(^|/)__pycache__/" OR _f MATCHES "\\.(pyc|pyo|so)$" OR _f MATCHES "(^|/)\\.")
      continue()
    endif()
    get_filename_component(_dir "${_f}" DIRECTORY)
    file(COPY "${SRC_DIR}/${_f}" DESTINATION "${STAGE}/schnee_probes/${_dir}")
  endforeach()
  file(COPY "${MODULE}" DESTINATION "${STAGE}/schnee_probes")
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

set(_addon_src ${CMAKE_SOURCE_DIR}/addon/schnee_probes)
file(STRINGS ${_addon_src}/__init__.py _ver_line REGEX "\"version\"[ ]*:[ ]*\\(")
if(_ver_line MATCHES "\\(([0-9]+)[ ]*,[ ]*([0-9]+)[ ]*,[ ]*([0-9]+)")
  set(SCHNEE_ADDON_VERSION "${CMAKE_MATCH_1}.${CMAKE_MATCH_2}.${CMAKE_MATCH_3}")
else()
  set(SCHNEE_ADDON_VERSION "${PROJECT_VERSION}")
endif()
set(SCHNEE_ADDON_ZIP ${CMAKE_SOURCE_DIR}/dist/schnee_probes-${SCHNEE_ADDON_VERSION}.zip
    CACHE INTERNAL "Path of the add-on zip")

file(GLOB_RECURSE _addon_inputs CONFIGURE_DEPENDS ${_addon_src}/*.py ${_addon_src}/*.toml ${_addon_src}/*.json)
list(FILTER _addon_inputs EXCLUDE REGEX "/__pycache__/")

add_custom_command(
  OUTPUT ${SCHNEE_ADDON_ZIP}
  COMMAND ${CMAKE_COMMAND} -DSRC_DIR=${_addon_src} -DMODULE=$<TARGET_FILE:_schnee_native>
          -DSTAGE=${CMAKE_BINARY_DIR}/addon_zip -DZIP=${SCHNEE_ADDON_ZIP}
          -P ${CMAKE_CURRENT_LIST_FILE}
  DEPENDS _schnee_native $<TARGET_FILE:_schnee_native> ${_addon_inputs} ${CMAKE_CURRENT_LIST_FILE}
  COMMENT "Packaging the add-on: dist/schnee_probes-${SCHNEE_ADDON_VERSION}.zip"
  VERBATIM)
add_custom_target(schnee_addon_zip ALL DEPENDS ${SCHNEE_ADDON_ZIP})
