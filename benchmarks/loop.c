/*
 * Benchmark baseline (c): a straightforward single-threaded C implementation of
 * the sampled-data closed loop (docs/semantics.md), for comparison with esoarm's compiled
 * batch engine.  Not shipped with the package; built by benchmarks/run.py with
 *     gcc -O3 -o loop loop.c -lm
 *
 * Inputs (written by run.py, little-endian binary):
 *   points.f64  P × 41 doubles per grid point:
 *               theta0, sigma, q, h, ts, b0 | rig[8] | obs[21] | ctl[6]
 *               (the packed vectors of esoarm.plants.lever_arm / observer / controller)
 *   ipoints.i64 P × 4 int64: n, nsub, delay, reference index
 *   refs.f64    M × 3 × NMAX doubles: theta_ref, omega_ref, accel_ref
 *   noises.f64  S × NMAX doubles: standard-normal draws of each seed
 *   runs.i64    R × 2 int64: point index, noise index
 * Usage: loop DIR P M S R NMAX  -> writes DIR/metrics_c.f64 (R × 4:
 *   rms_error, rms_u, max_abs_error, diverged) and prints the loop time [s].
 * Metrics use plain sequential sums (NumPy uses pairwise sums: differences of
 * a few ulp are expected).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

enum { INERTIA, GCOEF, FC, VS, VISC, DAMP, DFREQ, LAG };
enum { KIND, TS, B0, BETA1, BETA2, BETA3, PHI = 6, GAMMA = 15, GAIN = 18 };
enum { K1, K2, I0, CGCOEF, COMP, LIMIT };
#define DIVERGENCE_LIMIT 1e6

static double acceleration(double th, double om, double tau, double t, const double *r) {
    double friction = r[FC] * tanh(om / r[VS]) + r[VISC] * om;
    return (tau - r[GCOEF] * cos(th) - friction) / r[INERTIA] + r[DAMP] * sin(r[DFREQ] * t);
}

static void derivative(double th, double om, double tau, double u, double t, const double *r,
                       double *d) {
    if (r[LAG] > 0.0) {
        d[0] = om;
        d[1] = acceleration(th, om, tau, t, r);
        d[2] = (u - tau) / r[LAG];
    } else {
        d[0] = om;
        d[1] = acceleration(th, om, u, t, r);
        d[2] = 0.0;
    }
}

static void rk4(double *x, double u, double t, double h, const double *r) {
    double half = 0.5 * h, k1[3], k2[3], k3[3], k4[3];
    derivative(x[0], x[1], x[2], u, t, r, k1);
    derivative(x[0] + half * k1[0], x[1] + half * k1[1], x[2] + half * k1[2], u, t + half, r, k2);
    derivative(x[0] + half * k2[0], x[1] + half * k2[1], x[2] + half * k2[2], u, t + half, r, k3);
    derivative(x[0] + h * k3[0], x[1] + h * k3[1], x[2] + h * k3[2], u, t + h, r, k4);
    double sixth = h / 6.0;
    for (int i = 0; i < 3; i++) x[i] += sixth * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
}

static double quantize(double x, double q) { return q > 0.0 ? q * floor(x / q + 0.5) : x; }

static double saturate(double u, double lim) { return u > lim ? lim : (u < -lim ? -lim : u); }

/* one run; returns rows logged (negative if diverged) */
static long run(const double *fp, const long *ip, const double *ref, const double *noise,
                double *uhist, double *metrics) {
    const double *rig = fp + 6, *obs = fp + 14, *ctl = fp + 35;
    double theta0 = fp[0], sigma = fp[1], q = fp[2], h = fp[3], ts = fp[4], b0 = fp[5];
    long n = ip[0], nsub = ip[1], delay = ip[2];
    long nmax_stride = ip[4];
    const double *tref = ref, *dref = ref + nmax_stride, *ddref = ref + 2 * nmax_stride;
    double x[3] = {theta0, 0.0, 0.0};
    double z1 = quantize(theta0 + sigma * noise[0], q), z2 = 0.0, z3 = 0.0;
    double se = 0.0, su = 0.0, me = 0.0;
    long rows = n, k;
    int kind = (int)obs[KIND];
    for (k = 0; k < n; k++) {
        double tk = k * ts;
        double y = quantize(x[0] + sigma * noise[k], q);
        double h1 = z1, h2 = z2, h3 = z3;
        if (kind == 2) {
            double e = y - z1;
            h1 = z1 + obs[GAIN] * e; h2 = z2 + obs[GAIN + 1] * e; h3 = z3 + obs[GAIN + 2] * e;
        }
        double alpha = ddref[k] - ctl[K1] * (h2 - dref[k]) - ctl[K2] * (h1 - tref[k]);
        double beta = ctl[COMP] == 0.0 ? h3 : -ctl[CGCOEF] * cos(h1) / ctl[I0];
        double u = saturate(ctl[I0] * (alpha - beta), ctl[LIMIT]);
        uhist[k] = u;
        double ua = k >= delay ? uhist[k - delay] : 0.0;
        double err = x[0] - tref[k];
        se += err * err; su += u * u; if (fabs(err) > me) me = fabs(err);
        if (!isfinite(x[0] + h2 + h3 + u) || !(fabs(x[0]) < DIVERGENCE_LIMIT) ||
            !(fabs(h1) < DIVERGENCE_LIMIT)) { rows = -(k + 1); break; }
        if (kind == 0) {
            double e = y - z1, t = obs[TS];
            double d1 = z2 + obs[BETA1] * e, d2 = z3 + b0 * u + obs[BETA2] * e, d3 = obs[BETA3] * e;
            z1 += t * d1; z2 += t * d2; z3 += t * d3;
        } else {
            const double *P = obs + PHI, *G = obs + GAMMA, *L = obs + GAIN;
            double a1 = kind == 1 ? z1 : h1, a2 = kind == 1 ? z2 : h2, a3 = kind == 1 ? z3 : h3;
            double n1 = P[0] * a1 + P[1] * a2 + P[2] * a3 + G[0] * u;
            double n2 = P[3] * a1 + P[4] * a2 + P[5] * a3 + G[1] * u;
            double n3 = P[6] * a1 + P[7] * a2 + P[8] * a3 + G[2] * u;
            if (kind == 1) {
                double e = y - z1;
                n1 += L[0] * e; n2 += L[1] * e; n3 += L[2] * e;
            }
            z1 = n1; z2 = n2; z3 = n3;
        }
        for (long j = 0; j < nsub; j++) rk4(x, ua, tk + j * h, h, rig);
    }
    long m = rows < 0 ? -rows : rows;
    metrics[0] = sqrt(se / m);
    metrics[1] = sqrt(su / m);
    metrics[2] = me;
    metrics[3] = rows < 0 ? 1.0 : 0.0;
    return rows;
}

static void *load(const char *dir, const char *name, size_t bytes) {
    char path[4096];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *f = fopen(path, "rb");
    if (!f) { perror(path); exit(1); }
    void *buf = malloc(bytes);
    if (fread(buf, 1, bytes, f) != bytes) { fprintf(stderr, "short read %s\n", path); exit(1); }
    fclose(f);
    return buf;
}

int main(int argc, char **argv) {
    if (argc != 7) { fprintf(stderr, "usage: loop DIR P M S R NMAX\n"); return 2; }
    const char *dir = argv[1];
    long P = atol(argv[2]), M = atol(argv[3]), S = atol(argv[4]), R = atol(argv[5]);
    long NMAX = atol(argv[6]);
    double *pts = load(dir, "points.f64", sizeof(double) * P * 41);
    long *ipts = load(dir, "ipoints.i64", sizeof(long) * P * 4);
    double *refs = load(dir, "refs.f64", sizeof(double) * M * 3 * NMAX);
    double *noises = load(dir, "noises.f64", sizeof(double) * S * NMAX);
    long *runs = load(dir, "runs.i64", sizeof(long) * R * 2);
    double *out = malloc(sizeof(double) * R * 4);
    double *uhist = malloc(sizeof(double) * NMAX);
    struct timespec a, b;
    clock_gettime(CLOCK_MONOTONIC, &a);
    for (long r = 0; r < R; r++) {
        long p = runs[2 * r], s = runs[2 * r + 1];
        long ip[5];
        memcpy(ip, ipts + 4 * p, sizeof(long) * 4);
        ip[4] = NMAX;
        run(pts + 41 * p, ip, refs + ip[3] * 3 * NMAX, noises + s * NMAX, uhist, out + 4 * r);
    }
    clock_gettime(CLOCK_MONOTONIC, &b);
    printf("%.6f\n", (b.tv_sec - a.tv_sec) + 1e-9 * (b.tv_nsec - a.tv_nsec));
    char path[4096];
    snprintf(path, sizeof path, "%s/metrics_c.f64", dir);
    FILE *f = fopen(path, "wb");
    fwrite(out, sizeof(double), R * 4, f);
    fclose(f);
    return 0;
}
