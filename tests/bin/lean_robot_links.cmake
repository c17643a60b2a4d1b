# cmake -DBINARY=<certislam-robot> -P lean_robot_links.cmake: fails when the executable needs a
# shared library of PCL, OpenVDB or VTK (or TBB and Qt, which only they bring), i.e. when a
# library of the front end, mapping or keyframe I/O was linked into the back-end-only robot.
execute_process(COMMAND ldd ${BINARY} OUTPUT_VARIABLE libraries RESULT_VARIABLE status)
if(NOT status EQUAL 0)
  message(FATAL_ERROR "ldd ${BINARY} failed (${status})")
endif()
if(NOT libraries MATCHES "libzmq")
  message(FATAL_ERROR "ldd ${BINARY}: no libzmq in\n${libraries}")
endif()
string(REGEX MATCHALL "lib(pcl|openvdb|vtk|tbb|Qt5)[^ \t\n]*" heavy "${libraries}")
if(heavy)
  list(REMOVE_DUPLICATES heavy)
  message(FATAL_ERROR "${BINARY} links ${heavy}: the back-end-only robot must not (split the "
                      "library that brought them, see actors/CMakeLists.txt)")
endif()
message(STATUS "${BINARY}: no PCL, OpenVDB, VTK, TBB or Qt")
