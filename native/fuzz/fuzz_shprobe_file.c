/* libFuzzer target for the .shprobe *file* readers (issue 14): pb_shprobe_read_header and
 * pb_shprobe_read open the file, read the header first and then only the size it implies. Any byte
 * string, written to a regular file, must give exactly the verdict of the memory reader (same result
 * code; on success the same header and contents), with the path in front of every message and
 * never a crash, leak or out-of-bounds read (built with ASan/UBSan by tests/fuzz/run_shprobe_fuzz.sh). */
#define _POSIX_C_SOURCE 200809L
#include "schnee/pb_sh.h"
#include "schnee/pb_shprobe.h"

#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static char g_path[64];

static void remove_input(void) { unlink(g_path); }

static void write_input(const uint8_t *data, size_t size)
{
    if (!g_path[0]) {
        snprintf(g_path, sizeof g_path, "/tmp/fuzz_shprobe_file_%ld.shprobe", (long)getpid());
        atexit(remove_input);
    }
    int fd = open(g_path, O_WRONLY | O_CREAT | O_TRUNC, 0600);
    if (fd < 0) abort();
    for (size_t done = 0; done < size;) {
        ssize_t k = write(fd, data + done, size - done);
        if (k <= 0) abort();
        done += (size_t)k;
    }
    close(fd);
}

/* A file-reader error must carry the code, a message that starts with the path, and no output. */
static void check_rejection(pb_result r, const pb_error *err)
{
    size_t n = strlen(g_path);
    if (err->code != r || strncmp(err->message, g_path, n) != 0 || strncmp(err->message + n, ": ", 2) != 0) abort();
}

static bool same_header(const pb_shprobe *a, const pb_shprobe *b)
{
    return a->version == b->version && a->probe_count == b->probe_count && a->max_band == b->max_band &&
           memcmp(a->grid_dims, b->grid_dims, sizeof a->grid_dims) == 0 &&
           memcmp(a->grid_origin, b->grid_origin, sizeof a->grid_origin) == 0 &&
           memcmp(&a->grid_spacing, &b->grid_spacing, sizeof a->grid_spacing) == 0 &&
           memcmp(a->grid_axes, b->grid_axes, sizeof a->grid_axes) == 0 && a->representation == b->representation &&
           a->storage == b->storage && a->structure == b->structure && a->element_count == b->element_count &&
           a->hanging_count == b->hanging_count && a->root_level == b->root_level &&
           a->split_node_count == b->split_node_count;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    write_input(data, size);
    pb_shprobe *mem = NULL, *file = NULL, hdr;
    pb_error e_mem, e_file, e_hdr;
    memset(&e_mem, 0, sizeof e_mem);
    memset(&e_file, 0, sizeof e_file);
    memset(&e_hdr, 0, sizeof e_hdr);
    pb_result r_mem = pb_shprobe_read_memory(data, size, &mem, &e_mem);
    pb_result r_file = pb_shprobe_read(g_path, &file, &e_file);
    pb_result r_hdr = pb_shprobe_read_header(g_path, &hdr, &e_hdr);

    /* The file reader decides exactly as the memory reader, with the same detail after the path. */
    if (r_file != r_mem) abort();
    if (r_file != PB_SUCCESS) {
        check_rejection(r_file, &e_file);
        if (file != NULL || strcmp(e_file.message + strlen(g_path) + 2, e_mem.message) != 0) abort();
    }
    /* The header reader accepts whenever the full reader does (it checks a subset: the header and
     * the size), and then reports the same header. */
    if (r_hdr != PB_SUCCESS) {
        check_rejection(r_hdr, &e_hdr);
        if (r_file == PB_SUCCESS) abort();
    } else if (r_file == PB_SUCCESS && !same_header(&hdr, file)) {
        abort();
    }
    if (r_file == PB_SUCCESS) {
        size_t coeffs = (size_t)file->probe_count * pb_shprobe_colour_count(file) * 3u;
        if (!same_header(file, mem) || memcmp(file->coeffs, mem->coeffs, coeffs * sizeof(float)) != 0) abort();
        size_t n = file->element_count;
        if (file->structure == PB_SHPROBE_GRID) {
            size_t cells = (size_t)file->grid_dims[0] * file->grid_dims[1] * file->grid_dims[2];
            if (memcmp(file->grid, mem->grid, cells * sizeof(int32_t)) != 0) abort();
        } else if (file->structure == PB_SHPROBE_OCTREE || file->structure == PB_SHPROBE_KDTREE) {
            if (memcmp(file->leaves, mem->leaves, n * 16) != 0 ||
                memcmp(file->leaf_corners, mem->leaf_corners, n * 32) ||
                memcmp(file->hanging_sources, mem->hanging_sources, (size_t)file->hanging_count * 16) != 0 ||
                memcmp(file->hanging_weights, mem->hanging_weights, (size_t)file->hanging_count * 16) != 0)
                abort();
            if (file->structure == PB_SHPROBE_KDTREE &&
                memcmp(file->split_nodes, mem->split_nodes, (size_t)file->split_node_count * 4) != 0)
                abort();
        } else if (memcmp(file->tets, mem->tets, n * 16) != 0 ||
                   memcmp(file->tet_neighbours, mem->tet_neighbours, n * 16) != 0) {
            abort();
        }
    }
    pb_shprobe_destroy(mem);
    pb_shprobe_destroy(file);
    return 0;
}
