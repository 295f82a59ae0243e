# The CPython module's sources (native/CMakeLists.txt).
set(PB_PYTHON_SOURCES
  python/module.c
)
