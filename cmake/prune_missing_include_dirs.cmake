# The ROS 2 Jazzy PyPI wheels export CMake targets whose INTERFACE_INCLUDE_DIRECTORIES carry
# the wheel build host's Python include dir (/opt/python/...), which does not exist here and
# makes CMake's generate step fail. Drop non-existent absolute entries from every imported
# target (generator expressions are kept). On a normal ROS install nothing is removed.
function(actaim2_prune_missing_include_dirs)
  get_property(_targets DIRECTORY PROPERTY IMPORTED_TARGETS)
  foreach(_t IN LISTS _targets)
    get_target_property(_incs ${_t} INTERFACE_INCLUDE_DIRECTORIES)
    if(_incs)
      set(_kept "")
      foreach(_d IN LISTS _incs)
        if(_d MATCHES "^\\$<" OR NOT IS_ABSOLUTE "${_d}" OR EXISTS "${_d}")
          list(APPEND _kept "${_d}")
        endif()
      endforeach()
      set_target_properties(${_t} PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${_kept}")
    endif()
  endforeach()
endfunction()
