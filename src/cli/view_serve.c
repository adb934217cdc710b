/* view_serve.c: `crease view --serve DIR`: a tiny static-file server for the
 * page `crease view` writes, on 127.0.0.1 only (docs/view.md).
 *
 * Needed when the sequences lie in DIR/data/ beside the page: browsers refuse
 * fetch() from file:// pages. One connection at a time (a viewer's handful of
 * requests), GET and HEAD only, a request of at most 8 KiB read within 10 s,
 * paths of [A-Za-z0-9._-/] without ".." or a leading dot, regular files
 * under DIR only, Connection: close. Stops on SIGINT or SIGTERM (Ctrl-C) with
 * exit status 0.
 *
 * Left out: keep-alive, ranges, directory listings, percent-encoded names,
 * IPv6, anything but loopback. */
#define _GNU_SOURCE /* SOCK_CLOEXEC, MSG_NOSIGNAL */
#include "cli.h"

#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/time.h>
#include <unistd.h>

int view_serve(const char *dir, int port);

enum { REQUEST_MAX = 8192, IO_TIMEOUT_S = 10 };

static volatile sig_atomic_t stop_flag = 0;
static void on_signal(int sig) {
    (void)sig;
    stop_flag = 1;
}

static int send_all(int fd, const void *d, size_t n) {
    const char *p = d;
    while (n > 0) {
        ssize_t w = send(fd, p, n, MSG_NOSIGNAL);
        if (w < 0 && errno == EINTR) continue;
        if (w <= 0) return -1;
        p += w;
        n -= (size_t)w;
    }
    return 0;
}

static void reply_status(int fd, int code, const char *what) {
    char h[256];
    int n = snprintf(h, sizeof h,
                     "HTTP/1.1 %d %s\r\nContent-Type: text/plain\r\nContent-Length: %zu\r\n"
                     "Connection: close\r\n\r\n%s\n",
                     code, what, strlen(what) + 1, what);
    send_all(fd, h, (size_t)n);
}

static const char *content_type(const char *path) {
    const char *dot = strrchr(path, '.');
    if (!dot) return "application/octet-stream";
    if (strcmp(dot, ".html") == 0) return "text/html; charset=utf-8";
    if (strcmp(dot, ".js") == 0) return "text/javascript; charset=utf-8";
    if (strcmp(dot, ".png") == 0) return "image/png";
    if (strcmp(dot, ".json") == 0) return "application/json";
    return "application/octet-stream";
}

/* A path we serve: "/" or [A-Za-z0-9._-/]+, no "..", no component starting with '.'. */
static int safe_path(const char *p) {
    if (p[0] != '/') return 0;
    for (const char *c = p; *c; c++) {
        int ok = (*c >= 'a' && *c <= 'z') || (*c >= 'A' && *c <= 'Z') || (*c >= '0' && *c <= '9') ||
                 *c == '.' || *c == '_' || *c == '-' || *c == '/';
        if (!ok) return 0;
        if (*c == '/' && (c[1] == '.' || c[1] == '/')) return 0;
    }
    return 1;
}

static void handle(int fd, const char *dir) {
    char req[REQUEST_MAX + 1];
    size_t n = 0;
    while (n < REQUEST_MAX) {
        ssize_t r = recv(fd, req + n, REQUEST_MAX - n, 0);
        if (r < 0 && errno == EINTR && !stop_flag) continue;
        if (r <= 0) return;
        n += (size_t)r;
        req[n] = 0;
        if (strstr(req, "\r\n\r\n")) break;
    }
    req[n] = 0;
    if (!strstr(req, "\r\n\r\n")) return reply_status(fd, 431, "request too large");
    char method[8], target[1024];
    if (sscanf(req, "%7s %1023s", method, target) != 2) return reply_status(fd, 400, "bad request");
    int head = strcmp(method, "HEAD") == 0;
    if (!head && strcmp(method, "GET") != 0) return reply_status(fd, 405, "method not allowed");
    char *q = strpbrk(target, "?#");
    if (q) *q = 0;
    if (!safe_path(target)) return reply_status(fd, 404, "not found");
    char path[2200];
    snprintf(path, sizeof path, "%s%s%s", dir, target,
             target[strlen(target) - 1] == '/' ? "index.html" : "");
    int f = open(path, O_RDONLY | O_CLOEXEC);
    struct stat sb;
    if (f < 0 || fstat(f, &sb) != 0 || !S_ISREG(sb.st_mode)) {
        if (f >= 0) close(f);
        return reply_status(fd, 404, "not found");
    }
    char h[512];
    int hn = snprintf(h, sizeof h,
                      "HTTP/1.1 200 OK\r\nContent-Type: %s\r\nContent-Length: %lld\r\n"
                      "Cache-Control: no-cache\r\nConnection: close\r\n\r\n",
                      content_type(path), (long long)sb.st_size);
    if (send_all(fd, h, (size_t)hn) == 0 && !head) {
        char buf[65536];
        ssize_t r;
        while ((r = read(f, buf, sizeof buf)) > 0)
            if (send_all(fd, buf, (size_t)r) != 0) break;
    }
    close(f);
}

int view_serve(const char *dir, int port) {
    char index[2100];
    snprintf(index, sizeof index, "%s/index.html", dir);
    struct stat sb;
    if (stat(index, &sb) != 0) {
        fprintf(stderr, "crease: %s: no such page (write it with crease view SEQ -o %s)\n", index,
                dir);
        return CLI_BAD_INPUT;
    }
    int s = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    int one = 1;
    struct sockaddr_in a = {.sin_family = AF_INET, .sin_port = htons((uint16_t)port)};
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t alen = sizeof a;
    if (s < 0 || setsockopt(s, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one) != 0 ||
        bind(s, (struct sockaddr *)&a, sizeof a) != 0 || listen(s, 16) != 0 ||
        getsockname(s, (struct sockaddr *)&a, &alen) != 0) {
        fprintf(stderr, "crease: 127.0.0.1:%d: cannot listen: %s\n", port, strerror(errno));
        if (s >= 0) close(s);
        return CLI_BAD_INPUT;
    }
    struct sigaction sa = {.sa_handler = on_signal}; /* no SA_RESTART: accept() returns EINTR */
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    fprintf(stderr, "view: serving %s at http://127.0.0.1:%d/ (Ctrl-C stops)\n", dir,
            ntohs(a.sin_port));
    fflush(stderr);
    const struct timeval tv = {.tv_sec = IO_TIMEOUT_S};
    while (!stop_flag) {
        int c = accept(s, NULL, NULL);
        if (c < 0) {
            if (errno == EINTR || errno == ECONNABORTED) continue;
            fprintf(stderr, "crease: accept: %s\n", strerror(errno));
            close(s);
            return CLI_BAD_INPUT;
        }
        setsockopt(c, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
        setsockopt(c, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
        handle(c, dir);
        close(c);
    }
    close(s);
    fprintf(stderr, "view: stopped\n");
    return CLI_OK;
}
