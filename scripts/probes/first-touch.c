/* What a fresh page costs on this machine: maps SIZE MiB, optionally asks for transparent huge
 * pages, writes one byte a page (the first touch: the kernel clears each page, and on a virtual
 * machine the host may have to back it), then writes the whole block again (memory already
 * backed), three rounds in one process. docs/benchmarks.md, "The whole process on this
 * machine", quotes it.
 *
 *     gcc -O2 -o /tmp/first-touch scripts/probes/first-touch.c
 *     /tmp/first-touch 128 1    # 128 MiB on huge pages
 *     /tmp/first-touch 128 0    # the same on 4 KiB pages
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <time.h>

static double now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec + t.tv_nsec * 1e-9;
}

int main(int argc, char **argv) {
    if (argc != 3) {
        fprintf(stderr, "usage: %s SIZE_MIB HUGE(0|1)\n", argv[0]);
        return 2;
    }
    size_t mib = strtoul(argv[1], NULL, 10);
    int huge = atoi(argv[2]);
    size_t size = mib << 20;
    for (int round = 1; round <= 3; round++) {
        char *block = mmap(NULL, size, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
        if (block == MAP_FAILED) {
            perror("mmap");
            return 1;
        }
        if (huge && madvise(block, size, MADV_HUGEPAGE) != 0) {
            perror("madvise");
        }
        double start = now();
        for (size_t at = 0; at < size; at += 4096) {
            block[at] = 1;
        }
        double touched = now();
        memset(block, 2, size);
        double written = now();
        printf("round %d: %zu MiB, huge pages %d: first touch %.1f ms (%.2f GiB/s), written again %.1f ms\n",
               round, mib, huge, (touched - start) * 1e3, mib / 1024.0 / (touched - start),
               (written - touched) * 1e3);
        munmap(block, size);
    }
    return 0;
}
