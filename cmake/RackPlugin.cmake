# rack_add_plugin(<target> <sources>...): a component-class plug-in, a MODULE library
# that a host file names under `plugins:` (rackd dlopens it and calls its
#   extern "C" void rack_register_components(rack::ComponentRegistry&);
# see examples/out_of_tree_class/).
#
# The plug-in compiles against RACK's headers (rack::plugin_api: include path and
# C++20) and links no rack library: rackd exports its symbols (-rdynamic), and the
# plug-in's references to Component, Parameter, ... bind to those when it is loaded,
# so that there is one registry, one executor and one GDOS hub per process. Linking
# rack::core into a plug-in would give it a second copy of all three.
#
# Every plug-in carries the ABI stamp of the headers it compiles against (an ELF note,
# rack/core/plugin_abi.h): rackd refuses a plug-in whose stamp is not its own before it
# runs any of its code. rack_add_plugin() compiles the note in; a MODULE library made
# otherwise calls rack_plugin_abi_note(<target>).
#
# Used in the source tree (included by the top CMakeLists) and installed beside
# rackConfig.cmake for out-of-tree classes.
set(_RACK_PLUGIN_CMAKE_DIR "${CMAKE_CURRENT_LIST_DIR}")

function(rack_plugin_abi_note target)
  if(RACK_PLUGIN_ABI_NOTE_SOURCE)  # the source tree: generated at every build (core/CMakeLists.txt)
    target_sources(${target} PRIVATE "${RACK_PLUGIN_ABI_NOTE_SOURCE}")
    add_dependencies(${target} rack_plugin_abi_stamp)
  else()  # installed: the note of the installed headers, beside this file
    target_sources(${target} PRIVATE "${_RACK_PLUGIN_CMAKE_DIR}/rack_plugin_abi_note.cpp")
  endif()
endfunction()

function(rack_add_plugin target)
  if(ARGC LESS 2)
    message(FATAL_ERROR "rack_add_plugin(${target} <sources>...): no sources")
  endif()
  add_library(${target} MODULE ${ARGN})
  if(TARGET rack::plugin_api)
    target_link_libraries(${target} PRIVATE rack::plugin_api)
  else()
    target_link_libraries(${target} PRIVATE rack_plugin_api)
  endif()
  # -z now: every symbol bound when rackd loads the plug-in, not lazily in an RT cycle
  # (rackd itself links with -z now for the same reason).
  target_link_options(${target} PRIVATE -Wl,-z,now)
  rack_plugin_abi_note(${target})
endfunction()
