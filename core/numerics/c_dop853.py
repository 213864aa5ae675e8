"""The C source of ``dop853_c``: Hairer's explicit Runge–Kutta 8(5,3) with its 7th-order dense output.

The method is scipy's ``DOP853`` step for step — the same tableau, error
norm (the 5th- and 3rd-order estimates combined), step-size control and
initial step — with the stepping loop in C, so it reaches DOP853's accuracy
without Python per step.  The coefficients are those of
:class:`scipy.integrate.DOP853` (the published tables of Hairer, Nørsett and
Wanner), printed exactly (17 significant digits); the loop is ours.

The work array of a run holds ``D8_WORK × dim`` numbers: ``y``, ``ynew``, a
stage argument, the two error estimates, the error scale and a spare
evaluation, then the 16 stages ``K`` (12 of the step, the last-same-as-first
evaluation at its end, 3 more for the dense output of a step that holds
output times) and the 7 rows ``F`` of the interpolant.
"""

from __future__ import annotations

import re

__all__ = ["dop853_source"]


#: The tables of scipy.integrate.DOP853 (Hairer, Nørsett and Wanner's), printed exactly: A (the 12 stages, the
#: weights B as row 12, and the 3 stages of the dense output as rows 13–15), C (12: the step's end), E5, E3 and the
#: dense output's D.  Written out so that loading the runtime library needs no import of scipy.integrate (0.3 s);
#: tests/test_integrators.py checks them against SciPy's.
_TABLES = r"""
static const double D8_A[16][16] = {
    {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
    {0.05260015195876773, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
    {0.0197250569845379, 0.0591751709536137, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
    {0.02958758547680685, 0.0, 0.08876275643042054, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
    {0.2413651341592667, 0.0, -0.8845494793282861, 0.924834003261792, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
    {0.037037037037037035, 0.0, 0.0, 0.17082860872947386, 0.12546768756682242, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
    {0.037109375, 0.0, 0.0, 0.17025221101954405, 0.06021653898045596, -0.017578125, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
    {0.03709200011850479, 0.0, 0.0, 0.17038392571223998, 0.10726203044637328, -0.015319437748624402, 0.008273789163814023, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
    {0.6241109587160757, 0.0, 0.0, -3.3608926294469414, -0.868219346841726, 27.59209969944671, 20.154067550477894, -43.48988418106996, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
    {0.47766253643826434, 0.0, 0.0, -2.4881146199716677, -0.590290826836843, 21.230051448181193, 15.279233632882423, -33.28821096898486, -0.020331201708508627, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
    {-0.9371424300859873, 0.0, 0.0, 5.186372428844064, 1.0914373489967295, -8.149787010746927, -18.52006565999696, 22.739487099350505, 2.4936055526796523, -3.0467644718982196, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
    {2.273310147516538, 0.0, 0.0, -10.53449546673725, -2.0008720582248625, -17.9589318631188, 27.94888452941996, -2.8589982771350235, -8.87285693353063, 12.360567175794303, 0.6433927460157636, 0.0, 0.0, 0.0, 0.0, 0.0},
    {0.054293734116568765, 0.0, 0.0, 0.0, 0.0, 4.450312892752409, 1.8915178993145003, -5.801203960010585, 0.3111643669578199, -0.1521609496625161, 0.20136540080403034, 0.04471061572777259, 0.0, 0.0, 0.0, 0.0},
    {0.056167502283047954, 0.0, 0.0, 0.0, 0.0, 0.0, 0.25350021021662483, -0.2462390374708025, -0.12419142326381637, 0.15329179827876568, 0.00820105229563469, 0.007567897660545699, -0.008298, 0.0, 0.0, 0.0},
    {0.03183464816350214, 0.0, 0.0, 0.0, 0.0, 0.028300909672366776, 0.053541988307438566, -0.05492374857139099, 0.0, 0.0, -0.00010834732869724932, 0.0003825710908356584, -0.00034046500868740456, 0.1413124436746325, 0.0, 0.0},
    {-0.42889630158379194, 0.0, 0.0, 0.0, 0.0, -4.697621415361164, 7.683421196062599, 4.06898981839711, 0.3567271874552811, 0.0, 0.0, 0.0, -0.0013990241651590145, 2.9475147891527724, -9.15095847217987, 0.0}};
static const double D8_C[16] = {0.0, 0.05260015195876773, 0.0789002279381516, 0.1183503419072274, 0.2816496580927726, 0.3333333333333333, 0.25, 0.3076923076923077, 0.6512820512820513, 0.6, 0.8571428571428571, 1.0, 1.0, 0.1, 0.2, 0.7777777777777778};
static const double D8_E5[13] = {0.01312004499419488, 0.0, 0.0, 0.0, 0.0, -1.2251564463762044, -0.4957589496572502, 1.6643771824549864, -0.35032884874997366, 0.3341791187130175, 0.08192320648511571, -0.022355307863886294, 0.0};
static const double D8_E3[13] = {-0.18980075407240762, 0.0, 0.0, 0.0, 0.0, 4.450312892752409, 1.8915178993145003, -5.801203960010585, -0.4226823213237919, -0.1521609496625161, 0.20136540080403034, 0.02265179219836082, 0.0};
static const double D8_D[4][16] = {
    {-8.428938276109013, 0.0, 0.0, 0.0, 0.0, 0.5667149535193777, -3.0689499459498917, 2.38466765651207, 2.117034582445028, -0.871391583777973, 2.2404374302607883, 0.6315787787694688, -0.08899033645133331, 18.148505520854727, -9.194632392478356, -4.436036387594894},
    {10.427508642579134, 0.0, 0.0, 0.0, 0.0, 242.28349177525817, 165.20045171727028, -374.5467547226902, -22.113666853125306, 7.733432668472264, -30.674084731089398, -9.332130526430229, 15.697238121770845, -31.139403219565178, -9.35292435884448, 35.81684148639408},
    {19.985053242002433, 0.0, 0.0, 0.0, 0.0, -387.0373087493518, -189.17813819516758, 527.8081592054236, -11.57390253995963, 6.8812326946963, -1.0006050966910838, 0.7777137798053443, -2.778205752353508, -60.19669523126412, 84.32040550667716, 11.99229113618279},
    {-25.69393346270375, 0.0, 0.0, 0.0, 0.0, -154.18974869023643, -231.5293791760455, 357.6391179106141, 93.40532418362432, -37.45832313645163, 104.0996495089623, 29.8402934266605, -43.53345659001114, 96.32455395918828, -39.17726167561544, -149.72683625798564}};
"""


def dop853_source() -> str:
    """The C functions ``lg_dop853`` (a whole run on output times), ``lg_dop853_begin``, ``lg_dop853_step``,
    ``lg_dop853_prepare`` and ``lg_dop853_dense`` (one step at a time, for the events driver); they need ``rhs_fn``,
    ``rms_scaled``, ``fail_at``, ``start_state``, ``watched`` and ``bounded`` from the runtime library's loops."""
    return _TABLES + _combinations() + _LOOP


def _table(name: str) -> list[float]:
    """The numbers of the C table ``name`` of :data:`_TABLES`, row after row (our own constant text: parsed, never
    evaluated)."""
    body = re.search(rf"\b{name}(?:\[\d+\])+ = \{{(.*?)\}};", _TABLES, re.S).group(1)
    return [float(x) for x in re.findall(r"-?\d+\.\d*(?:e[+-]?\d+)?", body)]


def _sum(terms: list[tuple[float, int]], i: str = "i") -> str:
    """``0.0 + c0 * k0[i] + c3 * k3[i] + ...``: the terms with a nonzero coefficient, in ascending stage order.

    The dense loop this replaces added every ``A[s][j] * K[j][i]`` from 0.0 in that order; a zero coefficient adds
    +0.0 to a sum that is never -0.0 past its first term, so the result is the same to the last bit, in about half
    the arithmetic (58 of the 78 coefficients of the step, 16 of 26 of the error estimates are nonzero)."""
    return " + ".join(["0.0"] + [f"{c!r} * k{j}[{i}]" for c, j in terms])


def _pointers(stages) -> str:
    return " ".join(f"const double *restrict k{j} = K[{j}];" for j in sorted(set(stages)))


def _combinations() -> str:
    """The stage arguments, the error estimates and the interpolant's rows, written out with the nonzero
    coefficients of the tables only, each as a loop over the state that GCC vectorizes."""
    A = _table("D8_A")
    E5, E3, D = _table("D8_E5"), _table("D8_E3"), _table("D8_D")
    cases = []
    for s in range(1, 16):
        terms = [(A[16 * s + j], j) for j in range(s) if A[16 * s + j] != 0.0]
        cases.append(f"    case {s}: {{ {_pointers(j for _, j in terms)}\n"
                     f"        for (int i = 0; i < dim; i++) out[i] = y[i] + hs * ({_sum(terms)}); return; }}")
    e5 = [(c, j) for j, c in enumerate(E5) if c != 0.0]
    e3 = [(c, j) for j, c in enumerate(E3) if c != 0.0]
    rows = [[(D[16 * r + j], j) for j in range(16) if D[16 * r + j] != 0.0] for r in range(4)]
    dense = "\n".join(f"        F{3 + r}[i] = hs * ({_sum(terms)});" for r, terms in enumerate(rows))
    return f"""
/* out = y + hs * (sum over j < s of A[s][j] K[j]): the argument of stage s (1 to 15; 12 is the step's end). */
static void d8_stage(int s, int dim, const double *restrict y, double hs, double *const *K, double *restrict out) {{
    switch (s) {{
{chr(10).join(cases)}
    }}
}}

/* The 5th- and 3rd-order error estimates of a step, unscaled, into e5 and e3. */
static void d8_errors(int dim, double *const *K, double *restrict e5, double *restrict e3) {{
    {_pointers(j for _, j in e5 + e3)}
    for (int i = 0; i < dim; i++) {{
        e5[i] = {_sum(e5)};
        e3[i] = {_sum(e3)};
    }}
}}

/* The last four rows of the interpolant, F[3..6] = hs * (D[r] . K). */
static void d8_rows(int dim, double hs, double *const *K, double *const *F) {{
    {_pointers(j for terms in rows for _, j in terms)}
    double *restrict F3 = F[3], *restrict F4 = F[4], *restrict F5 = F[5], *restrict F6 = F[6];
    for (int i = 0; i < dim; i++) {{
{dense}
    }}
}}
"""


_LOOP = r"""
#define D8_WORK 30
static void d8_parts(int dim, double *work, double **K, double **F) {
    for (int s = 0; s < 16; s++) K[s] = work + (7 + s) * dim;
    for (int r = 0; r < 7; r++) F[r] = work + (23 + r) * dim;
}

/* K[0] = f(t0, y) and the first step to try (first_step, or scipy's select_initial_step with error order 7). */
static int d8_begin(rhs_fn f, const void *ctx, int dim, double t0, double t1, double rtol, double atol, double max_step,
                    double first_step, double *work, double *h, long *nfev, double *fail) {
    double *y = work, *ys = y + 2 * dim, *err = y + 3 * dim, *scale = y + 5 * dim, *f1 = y + 6 * dim, *K[16], *F[7];
    d8_parts(dim, work, K, F);
    int rc = f(ctx, inside(t0, t0, t1), y, K[0]); (*nfev)++;
    if (rc) { fail_at(dim, fail, t0, y); return rc; }
    *h = first_step;
    if (*h > 0.0) return 0;
    double length = t1 - t0;
    for (int i = 0; i < dim; i++) scale[i] = atol + fabs(y[i]) * rtol;
    double d0 = rms_scaled(dim, y, scale), d1 = rms_scaled(dim, K[0], scale), h0;
    h0 = (d0 < 1e-5 || d1 < 1e-5) ? 1e-6 : 0.01 * d0 / d1;
    if (h0 > length) h0 = length;
    for (int i = 0; i < dim; i++) ys[i] = y[i] + h0 * K[0][i];
    rc = f(ctx, t0 + h0, ys, f1); (*nfev)++;
    double d2 = 0.0;
    if (!rc) { for (int i = 0; i < dim; i++) err[i] = f1[i] - K[0][i]; d2 = rms_scaled(dim, err, scale) / h0; }
    double h1 = (d1 <= 1e-15 && d2 <= 1e-15) ? fmax(1e-6, h0 * 1e-3) : pow(0.01 / fmax(d1, d2), 1.0 / 8.0);
    *h = fmin(fmin(100 * h0, h1), fmin(length, max_step));
    return 0;
}

/* One accepted step from (t, y) with K[0] = f(t, y), trying *h first: on return ynew (= work + dim), K[12] = f at
   its end, and the step's length *hstep and end *tend; *h is the next step to try.  Status 0, or 1 singular matrix,
   3 step size too small. */
static int d8_step(rhs_fn f, const void *ctx, int dim, double t, double t1, double rtol, double atol, double max_step,
                   double *work, double *h, double *hstep, double *tend, long *nfev, long *nrej, double *fail) {
    const double SAFETY = 0.9, MIN_FACTOR = 0.2, MAX_FACTOR = 10.0, EXPONENT = -1.0 / 8.0;
    double *y = work, *ynew = y + dim, *ys = y + 2 * dim, *e5 = y + 3 * dim, *e3 = y + 4 * dim, *scale = y + 5 * dim;
    double *K[16], *F[7];
    d8_parts(dim, work, K, F);
    double min_step = 10.0 * fabs(nextafter(t, INFINITY) - t);
    if (*h > max_step) *h = max_step;
    else if (*h < min_step) *h = min_step;
    int rejected = 0, rc;
    for (;;) {
        if (*h < min_step) { fail_at(dim, fail, t, y); return 3; }
        double tnew = t + *h;
        if (tnew > t1) tnew = t1;
        double hs = tnew - t;
        *hstep = hs;
        *tend = tnew;
        int bad = 0;
        for (int s = 1; s <= 12 && !bad; s++) {
            double *target = (s == 12) ? ynew : ys;
            d8_stage(s, dim, y, hs, K, target);
            double ts = s == 12 ? inside(tnew, t, t1) : t + D8_C[s] * hs;
            rc = f(ctx, ts, target, K[s]); (*nfev)++;
            if (rc == 1) { fail_at(dim, fail, ts, target); return 1; }
            if (rc) bad = 1;
        }
        double norm;
        if (bad) norm = INFINITY;
        else {
            double s5 = 0.0, s3 = 0.0;
            d8_errors(dim, K, e5, e3);
            for (int i = 0; i < dim; i++) {
                scale[i] = atol + (fabs(y[i]) > fabs(ynew[i]) ? fabs(y[i]) : fabs(ynew[i])) * rtol;  /* (fmax: a call) */
                e5[i] /= scale[i];
                e3[i] /= scale[i];
                s5 += e5[i] * e5[i];
                s3 += e3[i] * e3[i];
            }
            norm = (s5 == 0.0 && s3 == 0.0) ? 0.0 : hs * s5 / sqrt((s5 + 0.01 * s3) * dim);
            if (!(norm == norm)) norm = INFINITY;
        }
        if (norm < 1.0) {
            double factor = norm == 0.0 ? MAX_FACTOR : fmin(MAX_FACTOR, SAFETY * pow(norm, EXPONENT));
            if (rejected && factor > 1.0) factor = 1.0;
            *h = hs * factor;
            return 0;
        }
        *h = hs * (norm == INFINITY ? MIN_FACTOR : fmax(MIN_FACTOR, SAFETY * pow(norm, EXPONENT)));
        rejected = 1;
        (*nrej)++;
    }
}

/* The interpolant of the last step (from t, length hs): three more stages, then its 7 rows F.  Status as f. */
static int d8_prepare(rhs_fn f, const void *ctx, int dim, double t, double hs, double *work, long *nfev, double *fail) {
    double *y = work, *ynew = y + dim, *ys = y + 2 * dim, *K[16], *F[7];
    d8_parts(dim, work, K, F);
    for (int s = 13; s < 16; s++) {
        d8_stage(s, dim, y, hs, K, ys);
        int rc = f(ctx, t + D8_C[s] * hs, ys, K[s]); (*nfev)++;
        if (rc) { fail_at(dim, fail, t + D8_C[s] * hs, ys); return rc; }
    }
    for (int i = 0; i < dim; i++) {
        double dy = ynew[i] - y[i];
        F[0][i] = dy;
        F[1][i] = hs * K[0][i] - dy;
        F[2][i] = 2 * dy - hs * (K[12][i] + K[0][i]);
    }
    d8_rows(dim, hs, K, F);
    return 0;
}

/* The 7th-order dense output of the last step at x = (s - t) / hs, from its rows F. */
static void d8_dense(int dim, const double *work, double x, double *out) {
    const double *y = work;
    for (int i = 0; i < dim; i++) {
        double acc = 0.0;
        for (int r = 6; r >= 0; r--) {
            acc += work[(23 + r) * dim + i];
            acc *= ((6 - r) % 2 == 0) ? x : 1.0 - x;
        }
        out[i] = y[i] + acc;
    }
}

static void d8_shift(int dim, double *work) {  /* y = ynew, K[0] = K[12] (first same as last) */
    memcpy(work, work + dim, dim * sizeof(double));
    memcpy(work + 7 * dim, work + 19 * dim, dim * sizeof(double));
}

/* DOP853 with error control (as scipy's DOP853) and its dense output on tout.  counts: nfev, steps, rejected.
   Status: 0 done; 1 singular matrix, 2 not finite, 3 step size too small, 4 diverged, 6 at its pace the run would
   need more than budget evaluations (judged from 131,072 on; budget 0: never), 7 stopped (state at fail).  watch
   (or NULL): the loop writes the time it has reached to watch[0] after each step, and stops when watch[1] is not 0
   (another thread asks it to: an interrupted run). */
static int dop853(rhs_fn f, const void *ctx, int dim, double t0, double t1, const double *y0, long nout,
                  const double *tout, double rtol, double atol, double max_step, double first_step, double budget,
                  volatile double *watch, double *Y, long *counts, double *fail, double *work) {
    double *y = work;
    const size_t row = dim * sizeof(double);
    long nfev = 0, nstep = 0, nrej = 0, o = 0;
    double t = t0, limit = start_state(dim, y, y0), h, hstep, tnew;
    int rc = d8_begin(f, ctx, dim, t0, t1, rtol, atol, max_step, first_step, work, &h, &nfev, fail);
    if (rc) { counts[0] = nfev; return rc; }
    while (o < nout && tout[o] <= t0) { memcpy(Y + o * dim, y, row); o++; }
    while (t < t1) {
        rc = d8_step(f, ctx, dim, t, t1, rtol, atol, max_step, work, &h, &hstep, &tnew, &nfev, &nrej, fail);
        if (rc) break;
        if (o < nout && tout[o] <= tnew) {
            rc = d8_prepare(f, ctx, dim, t, hstep, work, &nfev, fail);
            if (rc) break;
            while (o < nout && tout[o] <= tnew) { d8_dense(dim, work, (tout[o] - t) / hstep, Y + o * dim); o++; }
        }
        t = tnew;
        d8_shift(dim, work);
        nstep++;
        if (!bounded(dim, y, limit)) { fail_at(dim, fail, t, y); rc = 4; break; }
        rc = watched(dim, t0, t1, t, y, nfev, budget, watch, fail);
        if (rc) break;
    }
    counts[0] = nfev; counts[1] = nstep; counts[2] = nrej;
    return rc;
}

int lg_dop853(rhs_fn f, const void *ctx, int dim, double t0, double t1, const double *y0, long nout, const double *tout,
              double rtol, double atol, double max_step, double first_step, double budget, double *watch, double *Y,
              long *counts, double *fail) {
    double *work = malloc((size_t)D8_WORK * (dim > 0 ? dim : 1) * sizeof(double));
    if (!work) { fail_at(dim, fail, t0, y0); return 5; }
    int rc = dop853(f, ctx, dim, t0, t1, y0, nout, tout, rtol, atol, max_step, first_step, budget, watch, Y, counts,
                    fail, work);
    free(work);
    return rc;
}

/* DOP853 one step at a time, for drivers that stop between steps (events); as lg_dopri5_begin/step/dense, with
   D8_WORK * dim numbers of work.  lg_dop853_dense prepares the step's interpolant on its first call after a step
   (three evaluations, counted in counts[0]) and evaluates it at x in [0, 1]. */
int lg_dop853_begin(rhs_fn f, const void *ctx, int dim, double t0, double t1, double rtol, double atol, double max_step,
                    double first_step, double *work, double *h, long *counts, double *fail) {
    return d8_begin(f, ctx, dim, t0, t1, rtol, atol, max_step, first_step, work, h, counts, fail);
}

int lg_dop853_step(rhs_fn f, const void *ctx, int dim, int shift, double t, double t1, double rtol, double atol,
                   double max_step, double *work, double *h, double *hstep, double *tend, long *counts, double *fail) {
    if (shift) d8_shift(dim, work);
    return d8_step(f, ctx, dim, t, t1, rtol, atol, max_step, work, h, hstep, tend, counts, counts + 1, fail);
}

int lg_dop853_prepare(rhs_fn f, const void *ctx, int dim, double t, double hstep, double *work, long *counts,
                      double *fail) {
    return d8_prepare(f, ctx, dim, t, hstep, work, counts, fail);
}

void lg_dop853_dense(int dim, const double *work, double x, double *out) { d8_dense(dim, work, x, out); }
"""


# Many runs of one model in one call (lagrangian.numerics.ensemble): run s takes its parameters from P + s*np (its
# ctx), starts from Y0 + s*dim, writes Y + s*nout*dim, counts + 3*s, fail + s*(dim + 1) and status[s]; the model's
# energies at every output time go to E + s*nout*4 when E is given (lg_energies of the model's native library).
ENSEMBLE_SOURCE = r"""
typedef void (*energy_fn)(const void *ctx, long N, const double *t, const double *q, const double *v, double *out);

void lg_ensemble(int method, rhs_fn f, energy_fn energies, long S, int np, const double *P, int nq, int dim,
                 double t0, double t1, const double *Y0, long nout, const double *tout, double rtol, double atol,
                 double max_step, double budget, double *Y, long *counts, double *fail, int *status, double *E,
                 double *scratch) {
    for (long s = 0; s < S; s++) {
        const double *ctx = P + s * np;
        double *Ys = Y + s * nout * dim;
        status[s] = (method ? lg_dop853 : lg_dopri5)(f, ctx, dim, t0, t1, Y0 + s * dim, nout, tout, rtol, atol,
                                                      max_step, 0.0, budget, NULL, Ys, counts + 3 * s,
                                                      fail + s * (dim + 1));
        if (status[s] || !E || !energies) continue;
        /* scratch: q and v of every output time (rows), v of inertial coordinates from the state */
        for (long k = 0; k < nout; k++) {
            memcpy(scratch + k * nq, Ys + k * dim, nq * sizeof(double));
            memcpy(scratch + nout * nq + k * nq, Ys + k * dim + nq, (dim - nq) * sizeof(double));
        }
        energies(ctx, nout, tout, scratch, scratch + nout * nq, E + s * nout * 4);
    }
}
"""
