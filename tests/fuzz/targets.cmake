# The fuzz targets (docs/fuzzing.md), one per parser family: tests/fuzz/<name>_fuzz.cpp, its
# seed corpus in tests/fuzz/corpus/<name>/ and the inputs that once failed in
# tests/fuzz/regressions/<name>/. Read by tests/CMakeLists.txt (the <name>_corpus replays,
# normal compiler) and tests/fuzz/CMakeLists.txt (the libFuzzer build).
#
# MTCAL_FUZZ_LIBS_<name>: the libraries the target links. MTCAL_FUZZ_MUTATIONS_<name>: the
# seeded mutations its replay runs (each replay well under 5 s).
set(MTCAL_FUZZ_TARGETS
    interferometer_codec ballbar_codec probes_codec logger_codec tracker_codec
    linear_csv circle_csv thermal_csv est_csv model_curves columns_csv
    plan_json machine_json model_json gantry_measurements compensation_tables)

set(MTCAL_FUZZ_LIBS_interferometer_codec mtcal_interferometer_codec)
set(MTCAL_FUZZ_LIBS_ballbar_codec mtcal::drivers)
set(MTCAL_FUZZ_LIBS_probes_codec mtcal::drivers)
set(MTCAL_FUZZ_LIBS_logger_codec mtcal::drivers)
set(MTCAL_FUZZ_LIBS_tracker_codec mtcal::drivers)
set(MTCAL_FUZZ_LIBS_linear_csv mtcal::acquisition)
set(MTCAL_FUZZ_LIBS_circle_csv mtcal::acquisition spdlog::spdlog)
set(MTCAL_FUZZ_LIBS_thermal_csv mtcal::acquisition)
set(MTCAL_FUZZ_LIBS_est_csv mtcal::services)
set(MTCAL_FUZZ_LIBS_model_curves mtcal::acquisition mtcal::mocks)
set(MTCAL_FUZZ_LIBS_columns_csv mtcal::acquisition)
set(MTCAL_FUZZ_LIBS_plan_json mtcal::acquisition)
set(MTCAL_FUZZ_LIBS_machine_json mtcal::services)
set(MTCAL_FUZZ_LIBS_model_json mtcal::processing)
set(MTCAL_FUZZ_LIBS_gantry_measurements mtcal::acquisition)
set(MTCAL_FUZZ_LIBS_compensation_tables mtcal::processing)

foreach(name IN LISTS MTCAL_FUZZ_TARGETS)
  set(MTCAL_FUZZ_MUTATIONS_${name} 20000)
endforeach()
