# Fails unless the lcm-spy type jar lists a class for every lifmcr LCM type.
execute_process(COMMAND ${JAR_TOOL} tf ${JAR} OUTPUT_VARIABLE listing RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "cannot list ${JAR}")
endif()
foreach(type preview_image_t depth_image_t camera_extrinsics_t vicon_object_t vicon_frame_t
        stage_stats_t drop_count_t pipeline_stats_t)
  string(FIND "${listing}" "lifmcr_lcm/${type}.class" found)
  if(found EQUAL -1)
    message(FATAL_ERROR "${JAR} lacks lifmcr_lcm/${type}.class")
  endif()
endforeach()
message(STATUS "all lifmcr LCM types in ${JAR}")
