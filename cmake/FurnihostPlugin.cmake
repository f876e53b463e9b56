# furnihost_add_plugin(<kind> <name> SOURCES ... [LIBS ...] [TESTS ...] [TEST_LIBS ...] [INCLUDES ...])
#   Builds libfurnihost_<kind>_<name>.so into the build tree's plugin folder, installs it, and
#   adds each TESTS source as a GoogleTest executable registered with ctest. A directory may set
#   FURNIHOST_PLUGIN_BUILD_DIR (where the library lands) and FURNIHOST_PLUGIN_NO_INSTALL (e.g.
#   examples/: built and tested, never installed) before calling it.
#   The plugin links furnihost::sdk only (with --no-undefined: a call into the host library is a
#   link error); its tests run it through the host and link furnihost::host.
# The same file serves this tree and, installed in <prefix>/lib/cmake/furnihost, plugins built
# outside it against an install (find_package(furnihost)): there the library lands in
# <build>/plugins (load it with `furnihost --plugin-path <build>/plugins`), installs to
# <its prefix>/lib/furnihost/plugins, and its tests find it through FURNIHOST_PLUGIN_PATH.
if(NOT DEFINED FURNIHOST_PLUGIN_BUILD_DIR)
  set(FURNIHOST_PLUGIN_BUILD_DIR ${CMAKE_BINARY_DIR}/plugins)
endif()
if(NOT DEFINED FURNIHOST_PLUGIN_INSTALL_DIR)
  set(FURNIHOST_PLUGIN_INSTALL_DIR lib/furnihost/plugins)
endif()
if(NOT DEFINED FURNIHOST_NO_UNDEFINED)  # this tree sets it in framework/ (sanitizer builds: none)
  set(FURNIHOST_NO_UNDEFINED "LINKER:--no-undefined")
endif()

function(furnihost_add_plugin kind name)
  cmake_parse_arguments(P "" "" "SOURCES;LIBS;TESTS;TEST_LIBS;INCLUDES" ${ARGN})
  set(target furnihost_${kind}_${name})
  if(NOT TARGET furnihost_plugins)  # outside this tree: one target that builds them all
    add_custom_target(furnihost_plugins)
  endif()
  add_library(${target} MODULE ${P_SOURCES})
  target_link_libraries(${target} PRIVATE furnihost::sdk ${P_LIBS})
  target_link_options(${target} PRIVATE ${FURNIHOST_NO_UNDEFINED})
  if(P_INCLUDES)
    target_include_directories(${target} PRIVATE ${P_INCLUDES})
  endif()
  # Installed in <prefix>/lib/furnihost/plugins, beside <prefix>/lib/libfurnihost_sdk.so.
  set_target_properties(${target} PROPERTIES
    PREFIX "lib" OUTPUT_NAME ${target}
    LIBRARY_OUTPUT_DIRECTORY ${FURNIHOST_PLUGIN_BUILD_DIR}
    INSTALL_RPATH "$ORIGIN/../..")
  if(NOT FURNIHOST_PLUGIN_NO_INSTALL)
    install(TARGETS ${target} LIBRARY DESTINATION ${FURNIHOST_PLUGIN_INSTALL_DIR})
  endif()
  add_dependencies(furnihost_plugins ${target})
  if(FURNIHOST_BUILD_TESTS AND P_TESTS)
    set(source_dir ${PROJECT_SOURCE_DIR})
    if(FURNIHOST_FROM_PACKAGE)  # outside this tree: configs and data are the install's
      set(source_dir ${furnihost_SHARE_DIR})
    endif()
    if(FURNIHOST_FROM_PACKAGE AND NOT TARGET furnihost::testing)
      message(FATAL_ERROR "furnihost_add_plugin(${kind} ${name} TESTS ...): GoogleTest was not found "
                          "(install libgtest-dev, or configure with -DFURNIHOST_BUILD_TESTS=OFF)")
    endif()
    include(GoogleTest)
    foreach(src ${P_TESTS})
      get_filename_component(tname ${src} NAME_WE)
      set(tt ${target}_${tname})
      add_executable(${tt} ${src})
      target_link_libraries(${tt} PRIVATE furnihost::host furnihost::testing ${P_TEST_LIBS})
      if(P_INCLUDES)
        target_include_directories(${tt} PRIVATE ${P_INCLUDES})
      endif()
      if(FURNIHOST_FROM_PACKAGE)  # the tests' plugin folder is this build's
        target_compile_definitions(${tt} PRIVATE FURNIHOST_TEST_PLUGIN_DIR="${FURNIHOST_PLUGIN_BUILD_DIR}")
      endif()
      add_dependencies(${tt} furnihost_plugins)
      gtest_discover_tests(${tt} DISCOVERY_TIMEOUT 60
        PROPERTIES ENVIRONMENT "FURNIHOST_PLUGIN_PATH=${FURNIHOST_PLUGIN_BUILD_DIR};FURNIHOST_SOURCE_DIR=${source_dir}")
    endforeach()
  endif()
endfunction()
