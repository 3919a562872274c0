# Numerics part (included at the end of CMakeLists.txt): SUNDIALS integrators and KINSOL for the rod
# solver, multiple shooting, the work-precision and stability-map drivers, and their tests.
find_package(SUNDIALS 6.4 REQUIRED COMPONENTS cvodes kinsol)

target_sources(hydrojet_rod PRIVATE
  ${PROJECT_SOURCE_DIR}/src/rod/cvode_integrator.cpp
  ${PROJECT_SOURCE_DIR}/src/rod/multiple_shooting.cpp
  ${PROJECT_SOURCE_DIR}/src/rod/kinsol_newton.cpp
)
# One translation unit per compiled right-hand-side variant (see src/rod/kernel_impl.h).
foreach(v kirchhoff kirchhoff_precurved kirchhoff_weight kirchhoff_weight_precurved
          cosserat cosserat_precurved cosserat_weight cosserat_weight_precurved)
  target_sources(hydrojet_rod PRIVATE ${PROJECT_SOURCE_DIR}/src/rod/kernel_${v}.cpp)
endforeach()
target_link_libraries(hydrojet_rod PUBLIC SUNDIALS::cvodes SUNDIALS::kinsol)

string(TOUPPER "${CMAKE_BUILD_TYPE}" _hj_build_type)
# Drivers for scripts/work_precision and scripts/stability_map (CSV out; plots in scripts/plot_*.py).
foreach(tool work_precision stability_map)
  add_executable(${tool} ${PROJECT_SOURCE_DIR}/bench/${tool}.cpp)
  target_link_libraries(${tool} hydrojet_config)
  target_compile_definitions(${tool} PRIVATE HYDROJET_SOURCE_DIR="${PROJECT_SOURCE_DIR}"
    HYDROJET_CXX_FLAGS="${CMAKE_CXX_FLAGS} ${CMAKE_CXX_FLAGS_${_hj_build_type}}")
  set_target_properties(${tool} PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${CATKIN_DEVEL_PREFIX}/${CATKIN_PACKAGE_BIN_DESTINATION})
endforeach()

if(CATKIN_ENABLE_TESTING)
  foreach(t test_numerics_models test_numerics_extreme)
    catkin_add_gtest(${t} ${PROJECT_SOURCE_DIR}/test/${t}.cpp)
    target_link_libraries(${t} hydrojet_config GTest::gtest_main)
    target_compile_definitions(${t} PRIVATE ${HJ_TEST_DEFS})
  endforeach()
endif()
