/* The C library's builds of its math functions per CPU: README, *Tests*, "The same bits on every
 * machine" (a measurement, not in CI; run by scripts/libm_builds.sh).
 *
 *   libm_builds write FILE     writes N results of each function (double and float) for fixed
 *                              pseudo-random arguments in [-10, 10) (logarithms of |x|·100,
 *                              pow(|x|, 0.3·y))
 *   libm_builds compare A B    counts, per function, the results that differ between two files
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define N 5000000
#define F 17
static const char *NAMES[F] = {"atan",  "atan2", "exp",  "log",  "log10", "log2",
                               "sin",   "cos",   "tan",  "pow",  "hypot", "expf",
                               "logf",  "sinf",  "cosf", "powf", "atanf"};

static uint64_t state;
static double uniform(void) {
    state ^= state << 13;
    state ^= state >> 7;
    state ^= state << 17;
    return (double)(state >> 11) * (1.0 / 9007199254740992.0);
}

static double eval(int f, double x, double y) {
    switch (f) {
    case 0: return atan(x);
    case 1: return atan2(x, y);
    case 2: return exp(x);
    case 3: return log(fabs(x) * 100);
    case 4: return log10(fabs(x) * 100);
    case 5: return log2(fabs(x) * 100);
    case 6: return sin(x);
    case 7: return cos(x);
    case 8: return tan(x);
    case 9: return pow(fabs(x), y * 0.3);
    case 10: return hypot(x, y);
    case 11: return expf((float)x);
    case 12: return logf(fabsf((float)x) * 100);
    case 13: return sinf((float)x);
    case 14: return cosf((float)x);
    case 15: return powf(fabsf((float)x), (float)y * 0.3f);
    default: return atanf((float)x);
    }
}

int main(int argc, char **argv) {
    if (argc == 3 && strcmp(argv[1], "write") == 0) {
        FILE *out = fopen(argv[2], "wb");
        double *buf = malloc(N * sizeof(double));
        if (!out || !buf) return 1;
        for (int f = 0; f < F; f++) {
            state = 0x9E3779B97F4A7C15ull + (uint64_t)f;
            for (int i = 0; i < N; i++) {
                double x = (uniform() - 0.5) * 20, y = (uniform() - 0.5) * 20;
                buf[i] = eval(f, x, y);
            }
            if (fwrite(buf, sizeof(double), N, out) != N) return 1;
        }
        return fclose(out) != 0;
    }
    if (argc == 4 && strcmp(argv[1], "compare") == 0) {
        FILE *a = fopen(argv[2], "rb"), *b = fopen(argv[3], "rb");
        double *x = malloc(N * sizeof(double)), *y = malloc(N * sizeof(double));
        if (!a || !b || !x || !y) return 1;
        for (int f = 0; f < F; f++) {
            if (fread(x, sizeof(double), N, a) != N || fread(y, sizeof(double), N, b) != N) return 1;
            long differ = 0;
            for (int i = 0; i < N; i++) differ += memcmp(&x[i], &y[i], sizeof(double)) != 0;
            printf("%-6s %7ld of %d results differ\n", NAMES[f], differ, N);
        }
        return 0;
    }
    fprintf(stderr, "usage: %s write FILE | compare A B\n", argv[0]);
    return 2;
}
