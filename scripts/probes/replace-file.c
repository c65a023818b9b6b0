/* What replacing a large output costs on this machine's file system, as `tspace process` does
 * it: write a temporary file in 8 MiB writes, then rename it over the previous output. MODE 0
 * does just that; MODE 1 also has a second thread start the writeback of each 8 MiB as soon as
 * it is written (sync_file_range), so that the rename has no dirty pages left to flush; MODE 2
 * holds the previous output open across the rename and times its close (where its blocks are
 * freed); MODE 3 writes over the previous output in place instead (truncated on open, as
 * gltfpack and glTF-Transform write), with no temporary file and no rename; MODE 4 is MODE 1
 * with a third thread that, as the writes begin, drops the previous output's pages from the page
 * cache (posix_fadvise POSIX_FADV_DONTNEED), so that the rename does not free them. Run it in a
 * directory on the file system to measure; it writes DIR/replace-probe.out.
 * docs/benchmarks.md, "The whole process on this machine", quotes it.
 *
 *     gcc -O2 -pthread -o /tmp/replace-file scripts/probes/replace-file.c
 *     for i in 1 2 3 4; do for m in 0 1 2 3; do sleep 3; /tmp/replace-file target/tmp $m; done; done
 */
#define _GNU_SOURCE
#include <fcntl.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#define CHUNK (8 << 20)
#define SIZE (72 << 20)

static int fd;
static atomic_long written;
static atomic_int finished;

static double now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec + t.tv_nsec * 1e-9;
}

static const char *previous_output;
static double dropped_ms;

static void *drop_previous_pages(void *unused) {
    (void)unused;
    double start = now();
    int previous = open(previous_output, O_RDONLY);
    if (previous >= 0) {
        posix_fadvise(previous, 0, 0, POSIX_FADV_DONTNEED);
        close(previous);
    }
    dropped_ms = (now() - start) * 1e3;
    return NULL;
}

static void *start_writeback(void *unused) {
    (void)unused;
    long started = 0;
    for (;;) {
        long upto = atomic_load(&written);
        if (upto > started) {
            sync_file_range(fd, started, upto - started, SYNC_FILE_RANGE_WRITE);
            started = upto;
        } else if (atomic_load(&finished)) {
            return NULL;
        } else {
            usleep(200);
        }
    }
}

int main(int argc, char **argv) {
    if (argc != 3) {
        fprintf(stderr, "usage: %s DIR MODE(0|1|2|3|4)\n", argv[0]);
        return 2;
    }
    int mode = atoi(argv[2]);
    char temporary[4096], output[4096];
    snprintf(temporary, sizeof temporary, "%s/.replace-probe.tmp", argv[1]);
    snprintf(output, sizeof output, "%s/replace-probe.out", argv[1]);
    char *data = malloc(SIZE);
    memset(data, 7, SIZE);
    double start = now();
    const char *target = mode == 3 ? output : temporary;
    fd = open(target, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd < 0) {
        perror(target);
        return 1;
    }
    pthread_t helper, dropper;
    if (mode == 4) {
        previous_output = output;
        pthread_create(&dropper, NULL, drop_previous_pages, NULL);
    }
    if (mode == 1 || mode == 4) {
        pthread_create(&helper, NULL, start_writeback, NULL);
    }
    for (long at = 0; at < SIZE; at += CHUNK) {
        if (write(fd, data + at, CHUNK) != CHUNK) {
            perror("write");
            return 1;
        }
        atomic_store(&written, at + CHUNK);
    }
    atomic_store(&finished, 1);
    double wrote = now();
    if (mode == 1 || mode == 4) {
        pthread_join(helper, NULL);
    }
    if (mode == 4) {
        pthread_join(dropper, NULL);
        printf("previous output's pages dropped in %.1f ms; ", dropped_ms);
    }
    close(fd);
    if (mode == 3) {
        double closed = now();
        printf("mode 3: write %.1f ms, closed %.1f ms, total %.1f ms\n", (wrote - start) * 1e3,
               (closed - wrote) * 1e3, (closed - start) * 1e3);
        return 0;
    }
    int previous = mode == 2 ? open(output, O_RDONLY) : -1;
    double before_rename = now();
    if (rename(temporary, output) != 0) {
        perror("rename");
        return 1;
    }
    double renamed = now();
    if (previous >= 0) {
        close(previous);
    }
    double closed = now();
    printf("mode %d: write %.1f ms, rename %.1f ms, previous output closed %.1f ms, total %.1f ms\n",
           mode, (wrote - start) * 1e3, (renamed - before_rename) * 1e3, (closed - renamed) * 1e3,
           (closed - start) * 1e3);
    return 0;
}
