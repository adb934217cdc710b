/* arena.c: a bump allocator over one block, reset once per step. */
#include "crease/base.h"

#include <stdlib.h>

enum { ARENA_ALIGN = 64 };

cr_status cr_arena_init(cr_arena *a, size_t capacity, cr_error *err) {
    a->used = a->peak = 0;
    a->capacity = 0;
    a->base = aligned_alloc(ARENA_ALIGN, (capacity + ARENA_ALIGN - 1) / ARENA_ALIGN * ARENA_ALIGN);
    if (!a->base) return CR_FAIL(err, CR_ERR_MEMORY, "arena: cannot allocate %zu bytes", capacity);
    a->capacity = capacity;
    return CR_OK;
}

void cr_arena_free(cr_arena *a) {
    if (!a) return;
    free(a->base);
    a->base = NULL;
    a->capacity = a->used = a->peak = 0;
}

void *cr_arena_alloc(cr_arena *a, size_t bytes, cr_error *err) {
    size_t start = (a->used + ARENA_ALIGN - 1) / ARENA_ALIGN * ARENA_ALIGN;
    if (start > a->capacity || bytes > a->capacity - start) {
        CR_FAIL(err, CR_ERR_MEMORY, "arena exhausted: need %zu bytes, %zu of %zu available",
                bytes, a->capacity - (start < a->capacity ? start : a->capacity), a->capacity);
        return NULL;
    }
    a->used = start + bytes;
    if (a->used > a->peak) a->peak = a->used;
    return a->base + start;
}

void cr_arena_reset(cr_arena *a) {
    a->used = 0;
}

void cr_arena_rewind(cr_arena *a, size_t mark) {
    CR_ASSERT(mark <= a->used);
    a->used = mark;
}
