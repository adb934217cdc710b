/* fileio.c: whole-file reads, atomic writes (temp + rename), mkdir -p, extensions. */
#define _POSIX_C_SOURCE 200809L
#include "crease/base.h"

#include <ctype.h>
#include <dirent.h>
#include <errno.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

cr_status cr_file_read_all(const char *path, char **out, size_t *out_len, cr_error *err) {
    *out = NULL;
    FILE *fp = fopen(path, "rb");
    if (!fp) return CR_FAIL(err, CR_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    size_t cap = 1 << 16, len = 0;
    char *buf = malloc(cap);
    errno = 0;
    while (buf) {
        size_t n = fread(buf + len, 1, cap - len - 1, fp);
        len += n;
        if (len + 1 < cap) break;
        char *grown = realloc(buf, cap * 2);
        if (!grown) {
            free(buf);
            buf = NULL;
            break;
        }
        buf = grown;
        cap *= 2;
    }
    int read_error = ferror(fp), why = errno; /* EISDIR: a folder given for a file */
    fclose(fp);
    if (!buf) return CR_FAIL(err, CR_ERR_MEMORY, "%s: out of memory reading file", path);
    if (read_error) {
        free(buf);
        return CR_FAIL(err, CR_ERR_IO, "%s: read error%s%s", path, why ? ": " : "",
                       why ? strerror(why) : "");
    }
    buf[len] = 0;
    *out = buf;
    if (out_len) *out_len = len;
    return CR_OK;
}

cr_status cr_atomic_open(cr_atomic_file *f, const char *path, cr_error *err) {
    f->fp = NULL;
    if (strlen(path) >= sizeof f->path)
        return CR_FAIL(err, CR_ERR_INVALID, "%s: path too long", path);
    snprintf(f->path, sizeof f->path, "%s", path);
    snprintf(f->tmp_path, sizeof f->tmp_path, "%s.tmp.%ld", path, (long)getpid());
    f->fp = fopen(f->tmp_path, "wb");
    if (!f->fp)
        return CR_FAIL(err, CR_ERR_IO, "%s: cannot write: %s", f->tmp_path, strerror(errno));
    return CR_OK;
}

/* Remove `path`.tmp.<pid> files left by writers that were killed before their
 * commit: a pid that no longer runs on this machine. A live writer's (another
 * process writing the same file now) is kept. Best effort: failures are silent. */
static void remove_stale_temporaries(const char *path) {
    char dir[1024], prefix[1100];
    const char *slash = strrchr(path, '/');
    if (slash) {
        size_t n = (size_t)(slash - path);
        if (n == 0) n = 1; /* "/name": the root */
        if (n >= sizeof dir) return;
        memcpy(dir, path, n);
        dir[n] = 0;
    } else {
        snprintf(dir, sizeof dir, ".");
    }
    size_t plen = (size_t)snprintf(prefix, sizeof prefix, "%s.tmp.", slash ? slash + 1 : path);
    if (plen >= sizeof prefix) return;
    DIR *d = opendir(dir);
    if (!d) return;
    const long self = (long)getpid();
    for (struct dirent *e; (e = readdir(d)) != NULL;) {
        if (strncmp(e->d_name, prefix, plen) != 0) continue;
        const char *digits = e->d_name + plen;
        char *end = NULL;
        errno = 0;
        long pid = strtol(digits, &end, 10);
        if (!isdigit((unsigned char)digits[0]) || *end || errno || pid <= 0 || pid == self)
            continue;
        if (kill((pid_t)pid, 0) == 0 || errno != ESRCH) continue; /* alive, or not ours to ask */
        char stale[2200];
        if ((size_t)snprintf(stale, sizeof stale, "%s/%s", dir, e->d_name) < sizeof stale)
            remove(stale);
    }
    closedir(d);
}

cr_status cr_atomic_commit(cr_atomic_file *f, cr_error *err) {
    int bad = ferror(f->fp);
    bad |= fflush(f->fp) != 0;
    bad |= fsync(fileno(f->fp)) != 0 && errno != EINVAL;
    bad |= fclose(f->fp) != 0;
    f->fp = NULL;
    if (bad) {
        remove(f->tmp_path);
        return CR_FAIL(err, CR_ERR_IO, "%s: write failed: %s", f->path, strerror(errno));
    }
    if (rename(f->tmp_path, f->path) != 0) {
        int e = errno;
        remove(f->tmp_path);
        return CR_FAIL(err, CR_ERR_IO, "%s: cannot rename into place: %s", f->path, strerror(e));
    }
    remove_stale_temporaries(f->path);
    return CR_OK;
}

void cr_atomic_abort(cr_atomic_file *f) {
    if (f->fp) fclose(f->fp);
    f->fp = NULL;
    remove(f->tmp_path);
}

cr_status cr_mkdir_p(const char *path, cr_error *err) {
    char buf[1024];
    if (strlen(path) >= sizeof buf) return CR_FAIL(err, CR_ERR_INVALID, "%s: path too long", path);
    snprintf(buf, sizeof buf, "%s", path);
    for (char *p = buf + 1;; p++) {
        if (*p == '/' || *p == 0) {
            char c = *p;
            *p = 0;
            if (mkdir(buf, 0777) != 0 && errno != EEXIST)
                return CR_FAIL(err, CR_ERR_IO, "%s: cannot create directory: %s", buf,
                               strerror(errno));
            *p = c;
            if (c == 0) break;
        }
    }
    struct stat st;
    if (stat(path, &st) != 0 || !S_ISDIR(st.st_mode))
        return CR_FAIL(err, CR_ERR_IO, "%s: not a directory", path);
    return CR_OK;
}

void cr_path_ext(const char *path, char *out, size_t cap) {
    const char *slash = strrchr(path, '/');
    const char *dot = strrchr(path, '.');
    size_t n = 0;
    if (dot && (!slash || dot > slash) && cap > 0)
        for (const char *c = dot + 1; *c && n + 1 < cap; c++)
            out[n++] = (char)tolower((unsigned char)*c);
    if (cap > 0) out[n] = 0;
}
