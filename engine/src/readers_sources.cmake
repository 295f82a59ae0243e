# The viewer's file readers (no Vulkan): sv_readers and sv_readers_noimage (engine/CMakeLists.txt).
set(SV_READER_SOURCES
  src/sv_probes.c
  src/sv_probe_pack.c
  src/sv_probe_query.c
  src/sv_probe_vis.c
  src/sv_sky.c
)
