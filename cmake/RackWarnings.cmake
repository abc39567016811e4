# One place for compiler warnings and sanitizer flags (STYLE.md 12).
function(rack_set_warnings target)
  target_compile_options(${target} PRIVATE
    -Wall -Wextra -Wshadow -Wconversion -Wsign-conversion -Wold-style-cast
    -Wnon-virtual-dtor -Woverloaded-virtual -Wnull-dereference -Wformat=2)
  if(RACK_SANITIZER)
    target_compile_options(${target} PRIVATE -fsanitize=${RACK_SANITIZER} -fno-omit-frame-pointer)
    target_link_options(${target} PRIVATE -fsanitize=${RACK_SANITIZER})
  endif()
endfunction()
