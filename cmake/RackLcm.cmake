# LCM 1.3 as Debian ships it has no CMake config: find header, library and lcm-gen ourselves.
find_path(LCM_INCLUDE_DIR lcm/lcm-cpp.hpp REQUIRED)
find_library(LCM_LIBRARY lcm REQUIRED)
find_program(LCM_GEN lcm-gen REQUIRED)
if(NOT TARGET rack::lcm)
  add_library(rack_lcm_imported UNKNOWN IMPORTED)
  set_target_properties(rack_lcm_imported PROPERTIES
    IMPORTED_LOCATION ${LCM_LIBRARY}
    INTERFACE_INCLUDE_DIRECTORIES ${LCM_INCLUDE_DIR})
  add_library(rack::lcm ALIAS rack_lcm_imported)
endif()

# rack_lcm_gen(<out-var> <outdir> <files...>): C++ headers generated at build time (lcm-gen -x).
function(rack_lcm_gen out_var out_dir)
  set(headers)
  foreach(lcm_file ${ARGN})
    get_filename_component(abs ${lcm_file} ABSOLUTE)
    file(STRINGS ${abs} pkg_line REGEX "^package ")
    string(REGEX REPLACE "^package[ \t]+([a-zA-Z0-9_]+).*" "\\1" pkg "${pkg_line}")
    file(STRINGS ${abs} struct_lines REGEX "^struct ")
    foreach(line ${struct_lines})
      string(REGEX REPLACE "^struct[ \t]+([a-zA-Z0-9_]+).*" "\\1" name "${line}")
      list(APPEND headers ${out_dir}/${pkg}/${name}.hpp)
    endforeach()
    list(APPEND all_lcm ${abs})
  endforeach()
  add_custom_command(OUTPUT ${headers}
    COMMAND ${LCM_GEN} -x --cpp-hpath ${out_dir} ${all_lcm}
    DEPENDS ${all_lcm}
    COMMENT "lcm-gen: C++ types for TiMS on LCM")
  set(${out_var} ${headers} PARENT_SCOPE)
endfunction()
