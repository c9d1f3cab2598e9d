# qd_add_plugin(<name> SOURCES <src>... [LIBRARIES <lib>...] [OUTPUT_DIRECTORY <dir>] [NO_INSTALL])
#
# Builds the plugin library qd_<name>.so. The same function builds this repository's plugins and
# third-party ones (after find_package(qd)). The library is a MODULE (dlopen only), has hidden
# visibility (its only export is the QD_PLUGIN entry) and is linked with --no-undefined, so a
# missing core export is a link error rather than a dlopen error at run time. It is compiled with
# the core's flags (qd_use_core_flags below).
#
# qd_use_core_flags(<target>)
#
# Compiles <target> the way the core was compiled. qd_add_plugin() calls it; call it yourself for
# any other target that exchanges Eigen objects with the core or a plugin, such as a test that
# compiles a plugin's code (see qd/testing/conformance.hpp):
#  * the core's instruction-set flags (property QD_ARCH_FLAGS of qd::core, e.g. -march=native):
#    Eigen's alignment depends on them, and the host refuses a plugin whose build fingerprint
#    differs from the core's. They are applied PRIVATE, never exported with qd::core, so a
#    project's other targets keep their own flags;
#  * an optimised build when the project chose none: with no CMAKE_BUILD_TYPE (and no -O in
#    CMAKE_CXX_FLAGS) a single-configuration generator compiles at -O0, several times slower for
#    Eigen code; the target then gets CMake's Release flags (-O3 -DNDEBUG). A build type or -O
#    level the project sets is left alone.
include_guard(GLOBAL)
include(GNUInstallDirs)

function(qd_use_core_flags target)
  get_target_property(arch qd::core QD_ARCH_FLAGS)
  if(arch)
    target_compile_options(${target} PRIVATE ${arch})
  endif()
  if(NOT CMAKE_CXX_FLAGS MATCHES "(^| )-O")
    separate_arguments(release UNIX_COMMAND "${CMAKE_CXX_FLAGS_RELEASE}")
    target_compile_options(${target} PRIVATE "$<$<STREQUAL:$<CONFIG>,>:${release}>")
  endif()
endfunction()

function(qd_add_plugin name)
  cmake_parse_arguments(ARG "NO_INSTALL" "OUTPUT_DIRECTORY" "SOURCES;LIBRARIES" ${ARGN})
  if(NOT ARG_SOURCES)
    message(FATAL_ERROR "qd_add_plugin(${name}): SOURCES is required")
  endif()
  add_library(${name} MODULE ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE qd::plugin ${ARG_LIBRARIES})
  qd_use_core_flags(${name})
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
