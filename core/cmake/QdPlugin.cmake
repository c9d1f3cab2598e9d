# qd_add_plugin(<name> SOURCES <src>... [LIBRARIES <lib>...] [OUTPUT_DIRECTORY <dir>] [NO_INSTALL])
#
# Builds the plugin library qd_<name>.so. The same function builds this repository's plugins and
# third-party ones (after find_package(qd)). The library is a MODULE (dlopen only), has hidden
# visibility (its only export is the QD_PLUGIN entry) and is linked with --no-undefined, so a
# missing core export is a link error rather than a dlopen error at run time.
include_guard(GLOBAL)
include(GNUInstallDirs)

function(qd_add_plugin name)
  cmake_parse_arguments(ARG "NO_INSTALL" "OUTPUT_DIRECTORY" "SOURCES;LIBRARIES" ${ARGN})
  if(NOT ARG_SOURCES)
    message(FATAL_ERROR "qd_add_plugin(${name}): SOURCES is required")
  endif()
  add_library(${name} MODULE ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE qd::plugin ${ARG_LIBRARIES})
  if(TARGET qd_warnings)
    target_link_libraries(${name} PRIVATE qd_warnings)
  endif()
  set_target_properties(${name} PROPERTIES PREFIX "" OUTPUT_NAME "qd_${name}"
    CXX_VISIBILITY_PRESET hidden VISIBILITY_INLINES_HIDDEN ON
    INSTALL_RPATH "$ORIGIN/../..")
  if(ARG_OUTPUT_DIRECTORY)
    set_target_properties(${name} PROPERTIES LIBRARY_OUTPUT_DIRECTORY ${ARG_OUTPUT_DIRECTORY})
  elseif(DEFINED QD_PLUGIN_OUTPUT_DIR)
    set_target_properties(${name} PROPERTIES LIBRARY_OUTPUT_DIRECTORY ${QD_PLUGIN_OUTPUT_DIR})
  endif()
  target_link_options(${name} PRIVATE LINKER:--no-undefined)
  if(NOT ARG_NO_INSTALL)
    install(TARGETS ${name} LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}/qd/plugins)
  endif()
  if(TARGET qd_all_plugins)
    add_dependencies(qd_all_plugins ${name})
  endif()
endfunction()
