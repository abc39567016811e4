# rack_add_class(): a component class is one folder and one declaration.
#
#   rack_add_class(NAME MCL                       # the name host files use
#     ID 0x1E                                     # TiMS class id of its addresses
#     INTERFACE MCL                               # TiMS class name ("Chassis" for ChassisSim)
#     SUMMARY "Monte Carlo localisation ..."      # one line for --list-classes
#     TYPE rack::components::Mcl                  # the Component subclass (the factory)
#     HEADER mcl.h                                # declares TYPE (relative to the folder)
#     [DATA rack::components::kMclType]           # its sample type (DataTypeInfo), if any
#     [COMMANDS rack::components::kMclCommands]   # its class commands (CommandInfo[])
#     [DECLARES mcl_types.h ...]                  # headers that declare DATA and COMMANDS:
#                                                 # in the folder (relative to it), or an
#                                                 # interface several folders share
#                                                 # (rack/interfaces/declared_types.h)
#     [SOURCES a.cpp ...]                         # relative to the folder
#     [LIBS target ...]                           # linked PRIVATE
#     [PLUGIN module]                             # a plug-in (below), else built in
#     [UNLOCKED_DEPENDENCIES]                     # plug-in: its libraries run only in
#                                                 # non-RT work; rackd leaves them unlocked
#     [UNAVAILABLE "reason"])                     # cannot be built here (a library is
#                                                 # missing): a warning with the reason; its
#                                                 # id is still in class_ids.h
#
# Built-in classes are compiled into rack_components and registered by the generated
# rack::components::register_builtin() (rack_generate_builtin_classes(), called once
# after every folder is added). A PLUGIN class is compiled into the MODULE library
# rack_plugin_<module> (classes naming the same module share it: ChassisReplay and
# LadarReplay share their log), written to RACK_PLUGIN_OUTPUT_DIR (default
# <build>/plugins, which rackd searches when run from the build tree) with a manifest
# <NAME>.rack-class per class, and installed to ${CMAKE_INSTALL_LIBDIR}/rack/plugins.
# rackd loads a plug-in only when a host file names one of its classes.
#
# The TiMS class id of every class of the tree is generated into
# rack/components/class_ids.h (target rack::class_ids; rack::components brings it):
# rack::class_ids::k<TiMS class name> (kChassis, kScan2d for Scan2D, kMcl for MCL),
# for code that addresses a class by number (tests, bench, rack-gui's panels). tims/
# knows no class id but its own (kExecutor, kTool, kFirstUser).
#
# No program links a table of the classes: rackd learns them from the registry (built-in
# ones registered, plug-ins loaded by name), the tools from the executor's class
# descriptions (GET_CLASS), and TiMS learns a class's name when the registry adds the
# class. Only the fuzz harnesses link a list of the tree's declarations
# (rack::class_declarations, below), because they must reach every declared data type
# and command body, plug-ins' too, as plain functions on bytes without loading a plug-in.
include_guard(GLOBAL)
include(GNUInstallDirs)

set(RACK_PLUGIN_BUILD_DIR "${CMAKE_BINARY_DIR}/plugins" CACHE INTERNAL "plug-ins in the build tree")
set(RACK_PLUGIN_INSTALL_DIR "${CMAKE_INSTALL_FULL_LIBDIR}/rack/plugins" CACHE INTERNAL "installed plug-ins")

function(rack_add_class)
  cmake_parse_arguments(PARSE_ARGV 0 C "UNLOCKED_DEPENDENCIES"
                        "NAME;ID;INTERFACE;SUMMARY;TYPE;HEADER;DATA;COMMANDS;PLUGIN;OUTPUT_DIR;UNAVAILABLE"
                        "SOURCES;LIBS;DECLARES")
  foreach(required NAME ID TYPE HEADER SUMMARY)
    if(NOT C_${required})
      message(FATAL_ERROR "rack_add_class: ${required} missing (${CMAKE_CURRENT_LIST_FILE})")
    endif()
  endforeach()
  if(NOT C_NAME MATCHES "^[A-Za-z][A-Za-z0-9_]*$")
    message(FATAL_ERROR "rack_add_class: NAME '${C_NAME}' must be letters, digits and '_'")
  endif()
  math(EXPR id_value "${C_ID}")
  if(id_value LESS 3 OR id_value GREATER 254)
    message(FATAL_ERROR "rack_add_class(${C_NAME}): ID ${C_ID} must be 3..254 (1, 2 are the executor and tools)")
  endif()
  # Its id for rack/components/class_ids.h (rack_generate_builtin_classes), named after
  # its TiMS class name: classes of the tree only (a test's or an out-of-tree class
  # declares its own).
  set(tree_class FALSE)
  if(NOT C_OUTPUT_DIR)
    set(tree_class TRUE)
    set(id_name "${C_INTERFACE}")
    if(NOT id_name)
      set(id_name "${C_NAME}")
    endif()
    file(RELATIVE_PATH folder "${PROJECT_SOURCE_DIR}" "${CMAKE_CURRENT_SOURCE_DIR}")
    set_property(GLOBAL APPEND PROPERTY RACK_CLASS_IDS "${id_name}|${id_value}|${C_NAME}|${folder}")
  endif()
  if(C_UNAVAILABLE)
    message(WARNING "${C_UNAVAILABLE}: the ${C_NAME} class is not built")
    return()
  endif()
  string(REPLACE "\"" "\\\"" summary "${C_SUMMARY}")
  set(data "nullptr")
  if(C_DATA)
    set(data "&${C_DATA}")
  endif()
  set(commands "{}")
  if(C_COMMANDS)
    set(commands "std::span<const rack::CommandInfo>(${C_COMMANDS})")
  endif()
  # A DECLARES header in the folder is named relative to it (mcl_types.h); others by
  # their include path (rack/interfaces/declared_types.h, shared interfaces).
  set(declares "")
  foreach(h IN LISTS C_DECLARES)
    if(NOT IS_ABSOLUTE "${h}" AND EXISTS "${CMAKE_CURRENT_SOURCE_DIR}/${h}")
      set(h "${CMAKE_CURRENT_SOURCE_DIR}/${h}")
    endif()
    list(APPEND declares "${h}")
  endforeach()
  set(C_DECLARES "${declares}")
  set(includes "#include \"${CMAKE_CURRENT_SOURCE_DIR}/${C_HEADER}\"\n")
  foreach(h IN LISTS C_DECLARES)
    string(APPEND includes "#include \"${h}\"\n")
  endforeach()
  set(generated "${CMAKE_BINARY_DIR}/rack_classes/${C_NAME}_class.cpp")
  file(CONFIGURE OUTPUT "${generated}" CONTENT "// Generated by rack_add_class(${C_NAME}) from ${CMAKE_CURRENT_LIST_FILE}
#include <memory>
#include <span>

#include \"rack/core/registry.h\"
${includes}
rack::ComponentClass rack_class_${C_NAME}() {
  rack::ComponentClass c;
  c.impl = \"${C_NAME}\";
  c.class_id = ${C_ID};
  c.description = \"${summary}\";
  c.make = [] { return std::make_unique<${C_TYPE}>(); };
  c.data = ${data};
  c.commands = ${commands};
  c.interface_name = \"${C_INTERFACE}\";
  return c;
}
" @ONLY)
  list(TRANSFORM C_SOURCES PREPEND "${CMAKE_CURRENT_SOURCE_DIR}/")
  get_filename_component(parent "${CMAKE_CURRENT_SOURCE_DIR}" DIRECTORY)

  # The tree's declarations for the fuzz harnesses (header-only data: no factory).
  if(tree_class)
    set_property(GLOBAL APPEND PROPERTY RACK_CLASS_DECLARATIONS "${id_value}|${C_NAME}|${C_INTERFACE}|${data}|${commands}")
    foreach(h IN LISTS C_DECLARES)
      set_property(GLOBAL APPEND PROPERTY RACK_CLASS_DECLARATION_INCLUDES "${h}")
    endforeach()
  endif()

  if(NOT C_PLUGIN)
    target_sources(rack_components PRIVATE ${generated} ${C_SOURCES})
    target_include_directories(rack_components PRIVATE "${parent}" "${CMAKE_CURRENT_SOURCE_DIR}")
    if(C_LIBS)
      target_link_libraries(rack_components PRIVATE ${C_LIBS})
    endif()
    set_property(GLOBAL APPEND PROPERTY RACK_BUILTIN_CLASSES "${C_NAME}")
    return()
  endif()

  set(module rack_plugin_${C_PLUGIN})
  set(out "${RACK_PLUGIN_BUILD_DIR}")
  if(C_OUTPUT_DIR)
    set(out "${C_OUTPUT_DIR}")
  endif()
  if(NOT TARGET ${module})
    add_library(${module} MODULE)
    if(NOT C_OUTPUT_DIR)  # the tree's plug-ins: built with rackd (which does not link them)
      if(NOT TARGET rack_plugins)
        add_custom_target(rack_plugins ALL)
      endif()
      add_dependencies(rack_plugins ${module})
    endif()
    set_target_properties(${module} PROPERTIES LIBRARY_OUTPUT_DIRECTORY "${out}" PREFIX "lib"
                          INSTALL_RPATH "$ORIGIN/../..")
    # Every symbol resolved at link time: a plug-in that would fail dlopen(RTLD_NOW)
    # fails the build instead.
    target_link_options(${module} PRIVATE -Wl,--no-undefined)
    target_link_libraries(${module} PRIVATE rack::core)
    rack_plugin_abi_note(${module})  # its ABI stamp (cmake/RackPlugin.cmake)
    if(COMMAND rack_set_warnings)
      rack_set_warnings(${module})
    endif()
    # Deferred arguments are expanded when the call runs: the name goes in literally.
    cmake_language(EVAL CODE
      "cmake_language(DEFER DIRECTORY [[${CMAKE_SOURCE_DIR}]] CALL _rack_finish_plugin [[${C_PLUGIN}]])")
    if(NOT C_OUTPUT_DIR)
      install(TARGETS ${module} LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}/rack/plugins COMPONENT Runtime)
    endif()
  endif()
  target_sources(${module} PRIVATE ${generated} ${C_SOURCES})
  target_include_directories(${module} PRIVATE "${parent}" "${CMAKE_CURRENT_SOURCE_DIR}")
  if(C_LIBS)
    target_link_libraries(${module} PRIVATE ${C_LIBS})
  endif()
  set_property(GLOBAL APPEND PROPERTY RACK_PLUGIN_${C_PLUGIN}_CLASSES "${C_NAME}")
  set(lock_line "")
  if(C_UNLOCKED_DEPENDENCIES)
    set(lock_line "lock_dependencies no\n")
  endif()
  # The manifest: found by class name, read without loading the library.
  file(GENERATE OUTPUT "${out}/${C_NAME}.rack-class" CONTENT "# rack_add_class(${C_NAME}): ${CMAKE_CURRENT_LIST_FILE}
class ${C_NAME}
interface ${C_INTERFACE}
library $<TARGET_FILE_NAME:${module}>
summary ${C_SUMMARY}
${lock_line}")
  if(NOT C_OUTPUT_DIR)
    install(FILES "${out}/${C_NAME}.rack-class" DESTINATION ${CMAKE_INSTALL_LIBDIR}/rack/plugins COMPONENT Runtime)
  endif()
endfunction()

# The plug-in's entry point: registers each of its classes.
function(_rack_finish_plugin plugin)
  get_property(names GLOBAL PROPERTY RACK_PLUGIN_${plugin}_CLASSES)
  set(decls "")
  set(calls "")
  foreach(n IN LISTS names)
    string(APPEND decls "rack::ComponentClass rack_class_${n}();\n")
    string(APPEND calls "  registry.add(rack_class_${n}());\n")
  endforeach()
  set(file "${CMAKE_BINARY_DIR}/rack_classes/plugin_${plugin}.cpp")
  file(CONFIGURE OUTPUT "${file}" CONTENT "// Generated by rack_add_class (plug-in ${plugin})
#include \"rack/core/registry.h\"

${decls}
extern \"C\" void rack_register_components(rack::ComponentRegistry& registry) {
${calls}}
" @ONLY)
  target_sources(rack_plugin_${plugin} PRIVATE "${file}")
endfunction()

# rack::components::register_builtin() from every built-in declaration, and the list of
# the tree's declarations (rack_class_declarations) for the fuzz harnesses. Called once,
# after the class folders are added.
function(rack_generate_builtin_classes builtin_target)
  _rack_generate_class_ids()
  target_link_libraries(${builtin_target} PUBLIC rack::class_ids)
  get_property(names GLOBAL PROPERTY RACK_BUILTIN_CLASSES)
  set(decls "")
  set(calls "")
  foreach(n IN LISTS names)
    string(APPEND decls "rack::ComponentClass rack_class_${n}();\n")
    string(APPEND calls "  registry.add(rack_class_${n}());\n")
  endforeach()
  set(file "${CMAKE_BINARY_DIR}/rack_classes/builtin_classes.cpp")
  file(CONFIGURE OUTPUT "${file}" CONTENT "// Generated by rack_generate_builtin_classes (cmake/RackClass.cmake)
#include \"rack/components/builtin.h\"
#include \"rack/components/class_ids.h\"
#include \"rack/tims/address.h\"

${decls}
namespace rack::components {
void register_builtin(ComponentRegistry& registry) {
${calls}  // The names of the tree's plug-in classes too (the same name and id as a class above
  // is no conflict): addresses in host files and logs name them without loading them.
  for (const class_ids::TreeClass& c : class_ids::kTreeClasses) (void)tims::register_class_name(c.id, c.name);
}
}  // namespace rack::components
" @ONLY)
  target_sources(${builtin_target} PRIVATE "${file}")
  _rack_generate_class_declarations()
endfunction()

# rack/components/class_declarations.h and its library rack::class_declarations: each
# declaration of the tree (built-in and plug-in) as data, with no factory, no library of
# a class and no side effect (it registers no TiMS class name). For the fuzz harnesses
# only (tests/fuzz: payload, field_names), which feed bytes to every declared data type
# and command body without loading a plug-in; rackd, the tools and the SDK do not link
# it (PluginClassTest.ToolsLinkTheClientLibraryNotTheExecutor checks the tools).
function(_rack_generate_class_declarations)
  get_property(rows GLOBAL PROPERTY RACK_CLASS_DECLARATIONS)
  get_property(headers GLOBAL PROPERTY RACK_CLASS_DECLARATION_INCLUDES)
  list(REMOVE_DUPLICATES headers)
  set(includes "")
  foreach(h IN LISTS headers)
    string(APPEND includes "#include \"${h}\"\n")
  endforeach()
  set(entries "")
  foreach(row IN LISTS rows)
    string(REPLACE "|" ";" f "${row}")
    list(GET f 0 id)
    list(GET f 1 name)
    list(GET f 2 iface)
    list(GET f 3 data)
    list(GET f 4 commands)
    string(APPEND entries "    ClassDeclaration{${id}, \"${name}\", \"${iface}\", ${data}, ${commands}},\n")
  endforeach()
  set(dir "${CMAKE_BINARY_DIR}/rack_classes/include")
  file(CONFIGURE OUTPUT "${dir}/rack/components/class_declarations.h" CONTENT "// Generated by rack_generate_builtin_classes (cmake/RackClass.cmake): the
// rack_add_class declarations of the tree (built-in and plug-in classes) as data, for the
// fuzz harnesses, which reach every declared type without loading a plug-in. Programs
// learn classes from the registry and from class descriptions, not from this list.
//
// Real-time contract: constant data; RT-safe.
#pragma once

#include <cstdint>
#include <span>

#include \"rack/core/class_types.h\"

namespace rack::components {

struct ClassDeclaration {
  uint8_t class_id;
  const char* name;            // the name host files use (MCL, ChassisSim)
  const char* interface_name;  // its TiMS class name (MCL, Chassis)
  const DataTypeInfo* data;    // nullptr: it publishes no data
  std::span<const CommandInfo> commands;
};

[[nodiscard]] std::span<const ClassDeclaration> class_declarations() noexcept;

}  // namespace rack::components
" @ONLY)
  set(file "${CMAKE_BINARY_DIR}/rack_classes/class_declarations.cpp")
  file(CONFIGURE OUTPUT "${file}" CONTENT "// Generated by rack_generate_builtin_classes (cmake/RackClass.cmake) from the
// rack_add_class declarations of the tree.
#include \"rack/components/class_declarations.h\"

#include <span>

${includes}
namespace rack::components {
namespace {
const ClassDeclaration kDeclarations[] = {
${entries}};
}  // namespace

std::span<const ClassDeclaration> class_declarations() noexcept { return kDeclarations; }
}  // namespace rack::components
" @ONLY)
  if(NOT TARGET rack_class_declarations)
    add_library(rack_class_declarations STATIC "${file}")
    add_library(rack::class_declarations ALIAS rack_class_declarations)
    target_include_directories(rack_class_declarations PUBLIC $<BUILD_INTERFACE:${dir}>
                               PRIVATE ${PROJECT_SOURCE_DIR}/components)
    target_link_libraries(rack_class_declarations PUBLIC rack::interfaces)
    if(COMMAND rack_set_warnings)
      rack_set_warnings(rack_class_declarations)
    endif()
  endif()
endfunction()

# kChassis for Chassis, kScan2d for Scan2D, kMcl for MCL: an upper-case letter that
# follows an upper-case letter or a digit is lowered (the tree's constant names).
function(_rack_id_constant out name)
  string(LENGTH "${name}" n)
  math(EXPR last "${n} - 1")
  set(result "k")
  set(after_upper FALSE)
  foreach(i RANGE 0 ${last})
    string(SUBSTRING "${name}" ${i} 1 c)
    if(c MATCHES "[A-Z]")
      if(after_upper)
        string(TOLOWER "${c}" c)
      endif()
      set(after_upper TRUE)
    elseif(c MATCHES "[0-9]")
      set(after_upper TRUE)
    else()
      set(after_upper FALSE)
    endif()
    string(APPEND result "${c}")
  endforeach()
  set(${out} "${result}" PARENT_SCOPE)
endfunction()

# rack/components/class_ids.h from every rack_add_class of the tree: one constant per
# TiMS class name (classes that share an interface share its id; a name with two ids,
# or an id with two names, is an error here rather than at run time).
function(_rack_generate_class_ids)
  get_property(rows GLOBAL PROPERTY RACK_CLASS_IDS)
  set(by_id "")
  foreach(row IN LISTS rows)
    string(REPLACE "|" ";" f "${row}")
    list(GET f 0 name)
    list(GET f 1 id)
    list(GET f 2 impl)
    list(GET f 3 folder)
    if(DEFINED id_of_${name} AND NOT id_of_${name} EQUAL id)
      message(FATAL_ERROR "rack_add_class(${impl}): ${name} has ID ${id} here and ${id_of_${name}} in ${folder_of_${name}}")
    endif()
    if(DEFINED name_of_${id} AND NOT name_of_${id} STREQUAL name)
      message(FATAL_ERROR "rack_add_class(${impl}) in ${folder}: ID ${id} is ${name_of_${id}}'s already")
    endif()
    if(NOT DEFINED id_of_${name})
      list(APPEND by_id "${id}")
      set(id_of_${name} ${id})
      set(name_of_${id} ${name})
      set(folder_of_${name} ${folder})
    endif()
    list(APPEND impls_of_${name} "${impl}")
    list(APPEND folders_of_${name} "${folder}")
  endforeach()
  list(SORT by_id COMPARE NATURAL)
  set(lines "")
  set(table "")
  foreach(id IN LISTS by_id)
    set(name "${name_of_${id}}")
    _rack_id_constant(constant "${name}")
    math(EXPR hex "${id}" OUTPUT_FORMAT HEXADECIMAL)
    string(TOUPPER "${hex}" hex)
    string(REPLACE "0X" "0x" hex "${hex}")
    list(REMOVE_DUPLICATES folders_of_${name})
    list(JOIN impls_of_${name} ", " impls)
    list(JOIN folders_of_${name} " " folders)
    string(APPEND lines "inline constexpr uint8_t ${constant} = ${hex};  // ${name}: ${impls} (${folders})\n")
    string(APPEND table "    {${hex}, \"${name}\"},\n")
  endforeach()
  set(dir "${CMAKE_BINARY_DIR}/rack_classes/include")
  file(CONFIGURE OUTPUT "${dir}/rack/components/class_ids.h" CONTENT "// Generated by rack_generate_builtin_classes (cmake/RackClass.cmake) from the
// rack_add_class declarations of the tree: the TiMS class id of each class name, for
// code that addresses a class by number (tests, bench, rack-gui's panels). Classes
// that share an interface (Chassis) share its id. tims/ knows no class but its own.
//
// Real-time contract: constants.
#pragma once

#include <cstdint>

namespace rack::class_ids {

${lines}
// Every TiMS class name of the tree with its id, built-in and plug-in alike:
// register_builtin() registers them all, so that a host file can address a component
// of a plug-in class this host does not load (`Scan3D(1/0)` on another host).
struct TreeClass {
  uint8_t id;
  const char* name;
};
inline constexpr TreeClass kTreeClasses[] = {
${table}};

}  // namespace rack::class_ids
" @ONLY)
  if(NOT TARGET rack_class_ids)
    add_library(rack_class_ids INTERFACE)
    add_library(rack::class_ids ALIAS rack_class_ids)
    target_include_directories(rack_class_ids INTERFACE $<BUILD_INTERFACE:${dir}>)
  endif()
endfunction()
