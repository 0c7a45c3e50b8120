/* The plain compiled reference for benchmarks/bench_kernel.py: the same run-curve physics as the
   planner's integrator (planner/physics/run_curve.py, module doc), for the case the benchmark times
   (constant ratio from standstill, constant-speed hold, no ratio change), written as the plain loop
   one would write in C. Built with gcc -O2 at benchmark time; never part of the package.

   Per run: the ceiling c^2 at every node (target^2 = ratio^2 x on-board maximum^2, lowered by the
   service-brake curve to every lower target ahead and by the stopping-brake curve onto the marker),
   then Heun's step in w = v^2 under full notch (capped at a_max, not below coasting on a steep fall),
   capped by the ceiling and split at the crossing, time 2 ds / (v0 + v1) per piece.

   Two look-ups of the tractive-effort table are exported: run_batch bisects (as the planner's kernel does),
   run_batch_walk walks from the interval of the step before (speed changes little per step, so it moves at
   most an interval or two), the look-up a hand-written C loop would often use. */
#include <math.h>

static double interp(double x, int nt, const double *xp, const double *fp, int *hint) {
    if (x < xp[0]) return fp[0];
    if (x >= xp[nt - 1]) return fp[nt - 1];
    int lo;
    if (hint) {  /* walk from the last interval: xp[lo] <= x < xp[lo + 1] */
        lo = *hint;
        while (lo > 0 && xp[lo] > x) lo--;
        while (lo < nt - 2 && xp[lo + 1] <= x) lo++;
        *hint = lo;
    } else {
        int hi = nt - 1;
        lo = 0;
        while (hi - lo > 1) { int mid = (lo + hi) >> 1; if (xp[mid] <= x) lo = mid; else hi = mid; }
    }
    return (fp[lo + 1] - fp[lo]) / (xp[lo + 1] - xp[lo]) * (x - xp[lo]) + fp[lo];
}

static double accel(double v, double ag, double ram, double rbm, double rcm, double tfi, double amax,
                    int nt, const double *tsp, const double *tef, double *coast, int *hint) {
    double c = ag - (ram + v * (rbm + rcm * v));
    double a = c + interp(v, nt, tsp, tef, hint) * tfi;
    double cap = c > amax ? c : amax;
    *coast = c;
    return a < cap ? a : cap;
}

/* n runs over the grid s[0..m-1]; writes running time [s] and traction work / M_e [J/kg];
   c2 is scratch of m doubles. */
static void batch(int m, const double *s, const double *vn2, const double *ag, double b, double bstop,
                  int nt, const double *tsp, const double *tef, double amax,
                  int n, const double *ratio, const double *ram, const double *rbm, const double *rcm,
                  const double *tfi, double *c2, double *t_out, double *work_out, int walk) {
    double L = s[m - 1];
    for (int i = 0; i < n; i++) {
        int h = 0, *hint = walk ? &h : 0;
        double r2 = ratio[i] * ratio[i];
        double svc = r2 * vn2[m - 1];
        c2[m - 1] = 0.0;
        for (int k = m - 2; k >= 0; k--) {
            double up = svc + 2.0 * b * (s[k + 1] - s[k]), st = 2.0 * bstop * (L - s[k]);
            svc = r2 * vn2[k];
            if (up < svc) svc = up;
            c2[k] = st < svc ? st : svc;
        }
        double w = 0.0, v = 0.0, t = 0.0, work = 0.0, c0 = c2[0];
        for (int k = 0; k < m - 1; k++) {
            double ds = s[k + 1] - s[k], cs0, cs1;
            double a0 = accel(v, ag[k], ram[i], rbm[i], rcm[i], tfi[i], amax, nt, tsp, tef, &cs0, hint);
            double wp = w + 2.0 * ds * a0;
            double a1 = accel(sqrt(wp > 0 ? wp : 0), ag[k + 1], ram[i], rbm[i], rcm[i], tfi[i], amax,
                              nt, tsp, tef, &cs1, hint);
            double slope = a0 + a1, wend = w + slope * ds, c1 = c2[k + 1], frac = 1.0, w1 = wend;
            if (wend > c1) { frac = (w - c0) / ((w - c0) - (wend - c1)); w1 = c1; }
            double xc = frac * ds, wc = w + slope * xc, vc = sqrt(wc), v1 = sqrt(w1), rest = ds - xc;
            double cb = 0.5 * (cs0 + cs1), wk = 0.5 * (w1 - wc) - rest * cb;
            t += 2.0 * (xc / (v + vc) + rest / (vc + v1));
            work += xc * (0.5 * slope - cb) + (wk > 0 ? wk : 0);
            w = w1; v = v1; c0 = c1;
        }
        t_out[i] = t;
        work_out[i] = work;
    }
}

void run_batch(int m, const double *s, const double *vn2, const double *ag, double b, double bstop,
               int nt, const double *tsp, const double *tef, double amax,
               int n, const double *ratio, const double *ram, const double *rbm, const double *rcm,
               const double *tfi, double *c2, double *t_out, double *work_out) {
    batch(m, s, vn2, ag, b, bstop, nt, tsp, tef, amax, n, ratio, ram, rbm, rcm, tfi, c2, t_out, work_out, 0);
}

void run_batch_walk(int m, const double *s, const double *vn2, const double *ag, double b, double bstop,
                    int nt, const double *tsp, const double *tef, double amax,
                    int n, const double *ratio, const double *ram, const double *rbm, const double *rcm,
                    const double *tfi, double *c2, double *t_out, double *work_out) {
    batch(m, s, vn2, ag, b, bstop, nt, tsp, tef, amax, n, ratio, ram, rbm, rcm, tfi, c2, t_out, work_out, 1);
}
