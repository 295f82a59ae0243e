/* Internal (not installed): the Morton (Z-order) code of a lattice point, shared by the corner
 * octree (pb_interp.c) and the version 3 reader's leaf-order check (pb_shprobe.c), which must agree. */
#ifndef SCHNEE_PB_MORTON_H
#define SCHNEE_PB_MORTON_H

#include <stdint.h>

/* The low 21 bits of v spread to every third bit. */
static inline uint64_t pb_spread21_(uint64_t v)
{
    v &= 0x1fffff;
    v = (v | v << 32) & UINT64_C(0x1f00000000ffff);
    v = (v | v << 16) & UINT64_C(0x1f0000ff0000ff);
    v = (v | v << 8) & UINT64_C(0x100f00f00f00f00f);
    v = (v | v << 4) & UINT64_C(0x10c30c30c30c30c3);
    v = (v | v << 2) & UINT64_C(0x1249249249249249);
    return v;
}

/* z most significant, as the placement's probe order (docs/placement.md, "Probe order"). */
static inline uint64_t pb_morton3_(uint32_t x, uint32_t y, uint32_t z)
{
    return pb_spread21_(x) | pb_spread21_(y) << 1 | pb_spread21_(z) << 2;
}

#endif
