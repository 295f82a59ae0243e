# The CPython module's sources (native/CMakeLists.txt): module.c (module, helpers) and one file per
# area of the core (native/python/mod_common.h lists them).
set(PB_PYTHON_SOURCES
  python/module.c
  python/mod_sh.c
  python/mod_placement.c
  python/mod_shprobe.c
  python/mod_interp.c
  python/mod_refine.c
  python/mod_direct.c
  python/mod_bricks.c
  python/mod_grid_field.c
)
