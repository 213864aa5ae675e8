"""FMI 2.0 export: a model as a Functional Mock-up Unit built from its generated C.

:func:`export` writes an FMU (:meth:`lagrangian.Model.to_fmu`), for model exchange (``kind="model-exchange"``: the
importing tool integrates the states) or co-simulation (``"co-simulation"``: each communication step is one run of
the DOP853 loop in C that ``Model.simulate`` runs by default, at the experiment's tolerance, else ``rtol=1e-9``, and
``atol = rtol / 1000``): a zip holding

- ``modelDescription.xml`` — the states (the coordinates by name, ``theta_j1``, and the rates of those with
  inertia as results name them, ``theta_j1'``; outputs, ``initial="exact"``), their derivatives
  (``der(theta_j1)``, ``der(theta_j1')``), and the parameters by their ``parameter_values`` names (tunable,
  with units where the component declares one), except the signals of sources and loads given as numbers
  (``E_V1``, ``F_F``), which are continuous inputs (``causality="input"``) that the importing tool may change at
  any time (see :func:`_inputs` for which signals qualify);
- ``binaries/<platform>/<modelIdentifier>.<so|dylib|dll>`` — built here by the C compiler models use;
- ``sources/<modelIdentifier>.c`` — the one C file of that library, so that other platforms build it (``cc
  -shared -fPIC <id>.c -lm``; define ``FMI2_FUNCTION_PREFIX`` to prefix the fmi2 functions).

The C is the model's native source that reads its parameters at run time
(:func:`lagrangian.numerics.c_source.parametric_source`: the tapes as straight-line C, the dense LU solve of
``A u = b``), followed by the fmi2 functions, which call its ``lg_rhs`` with the FMU's parameter values, and the
stepping loop (:mod:`lagrangian.numerics.c_dop853`) that ``fmi2DoStep`` runs; it needs
nothing but the C library and ``libm``.  Names enter the C only through
:func:`~lagrangian.numerics.c_source.c_comment`; in the XML they pass :func:`xml_text`.  The binary is kept in the
compiled-code cache (keyed by its source), so exporting a model again compiles nothing.

Refused by name (:class:`~lagrangian.ModelError`), as not built yet: constraints (loop closures,
rolling: their consistent start is not checked by the FMU) and constraints on velocities, signals that switch in
time (pulses, steps: they need time events; give such a source as a number instead, and the importing tool switches
the input), stick–slip friction (events), and signals or loads given as Python
callables (C cannot call them).
"""

from __future__ import annotations

import hashlib
import math
import os
import re
import struct
import sys
import tempfile
import uuid
import zipfile
from pathlib import Path

from ..base.component import t
from ..base.units import coordinate_unit
from ..derivation.assembly import driven
from ..errors import ModelError
from .c_build import _cache, _key, _libraries, compiler
from .c_dop853 import dop853_source
from .c_source import _LOOPS, _Unavailable, c_comment, parametric_source
from .simulation import check_start, initial_state
from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())

__all__ = ["export", "model_identifier", "xml_text", "KINDS"]

#: What ``Model.to_fmu`` builds (``kind=``).
KINDS = ("model-exchange", "co-simulation")

_IDENTIFIER = re.compile(r"^[A-Za-z_][A-Za-z0-9_]{0,63}$")
# Characters XML 1.0 cannot hold at all (not even escaped).
_NOT_XML = re.compile("[\x00-\x08\x0b\x0c\x0e-\x1f\ufffe\uffff]")


def xml_text(text: str) -> str:
    """``text`` as XML character data or an attribute value (between double quotes): the only way names enter
    ``modelDescription.xml``.  ``& < > " '`` become entities; characters XML cannot hold become ``?``.

    >>> xml_text('a<b> & "c" \\x01')
    'a&lt;b&gt; &amp; &quot;c&quot; ?'
    """
    text = _NOT_XML.sub("?", str(text))
    for raw, entity in (("&", "&amp;"), ("<", "&lt;"), (">", "&gt;"), ('"', "&quot;"), ("'", "&apos;")):
        text = text.replace(raw, entity)
    return text.replace("&apos;", "'")  # an apostrophe is fine inside double quotes ("theta_j1'")


def model_identifier(name: str, given: str | None = None) -> str:
    """The FMU's ``modelIdentifier`` (the name of its library and source file): ``given`` when it is a C
    identifier (checked), else one derived from the model's ``name`` (``"double pendulum"`` →
    ``double_pendulum``).

    >>> model_identifier("double pendulum"), model_identifier("3 masses"), model_identifier("x", "my_fmu")
    ('double_pendulum', 'm_3_masses', 'my_fmu')
    """
    if given is not None:
        if not isinstance(given, str) or not _IDENTIFIER.match(given):
            raise ModelError(f"to_fmu: model_identifier must be a C identifier (a letter or _, then letters, digits "
                             f"or _; at most 64 characters), got {given!r:.80}; or leave it out to derive one from "
                             f"the model's name.")
        return given
    derived = re.sub(r"_+", "_", re.sub(r"[^A-Za-z0-9_]", "_", str(name))).strip("_")[:60] or "model"
    return derived if _IDENTIFIER.match(derived) else f"m_{derived}"


# -- units ------------------------------------------------------------------------------------------------------
_BASE = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")
_UNITS = {  # SI units as exponents of the FMI base units (kg, m, s, A, K, mol, cd, rad)
    "kg": (1, 0, 0, 0, 0, 0, 0, 0), "m": (0, 1, 0, 0, 0, 0, 0, 0), "s": (0, 0, 1, 0, 0, 0, 0, 0),
    "A": (0, 0, 0, 1, 0, 0, 0, 0), "K": (0, 0, 0, 0, 1, 0, 0, 0), "rad": (0, 0, 0, 0, 0, 0, 0, 1),
    "N": (1, 1, -2, 0, 0, 0, 0, 0), "J": (1, 2, -2, 0, 0, 0, 0, 0), "W": (1, 2, -3, 0, 0, 0, 0, 0),
    "Pa": (1, -1, -2, 0, 0, 0, 0, 0), "Hz": (0, 0, -1, 0, 0, 0, 0, 0), "C": (0, 0, 1, 1, 0, 0, 0, 0),
    "V": (1, 2, -3, -1, 0, 0, 0, 0), "Ω": (1, 2, -3, -2, 0, 0, 0, 0), "H": (1, 2, -2, -2, 0, 0, 0, 0),
    "F": (-1, -2, 4, 2, 0, 0, 0, 0), "Wb": (1, 2, -2, -1, 0, 0, 0, 0), "T": (1, 0, -2, -1, 0, 0, 0, 0),
}
_POWER = re.compile(r"^([A-Za-zΩ]+)(?:\^(-?\d)|(²)|(³))?$")


def _unit_exponents(unit: str) -> tuple[str, tuple[int, ...]] | None:
    """``(name, exponents)`` of a unit as parameters declare them (``"N s/m"``, ``"m/s²"``; the part before an
    ``=``), or ``None`` when it is empty or holds a unit outside :data:`_UNITS`."""
    name = unit.split("=")[0].strip()
    if not name:
        return None
    total = [0] * len(_BASE)
    for sign, part in zip((1, -1), name.split("/", 1) + [""] * (1 - name.count("/"))):
        for token in filter(None, re.split(r"[ *·]+", part)):
            match = _POWER.match(token)
            if not match or match.group(1) not in _UNITS:
                return None
            power = int(match.group(2) or (2 if match.group(3) else 3 if match.group(4) else 1))
            total = [t + sign * power * e for t, e in zip(total, _UNITS[match.group(1)])]
    return name, tuple(total)


# -- what the FMU holds -------------------------------------------------------------------------------------------
def _refuse(model, kind: str) -> None:
    """A :class:`ModelError` naming what the FMU cannot hold yet (see the module's text)."""
    if kind not in KINDS:
        raise ModelError(f"to_fmu: kind must be one of {', '.join(map(repr, KINDS))}, not {kind!r:.60}.")
    sticking = [c.name for c in model.components.values() if c.params.get("stick_slip")]
    if sticking:
        raise ModelError(f"to_fmu: model {model.name!r} has friction with stick_slip=True ({', '.join(map(repr, sticking))}), "
                         f"whose sticking and slipping are events, not in FMUs yet; export it with stick_slip=False "
                         f"(the regularized friction) or run it with lagrangian.stick_slip.simulate.")
    eq, name = model.eq, model.name
    scan = eq.scan()
    held = sorted(set(scan["callables"]) | set(getattr(model.assembly, "state_callables", ())))
    if held or scan["derivatives"]:
        raise ModelError(f"to_fmu: model {name!r} has signals or loads given as Python callables "
                         f"({', '.join(held) or 'their derivatives'}), which the FMU's C cannot call; give them as "
                         f"SymPy expressions of t (and of lagrangian.coordinate(...), lagrangian.rate(...)).")
    switches = eq.time_switches()
    if switches:
        raise ModelError(f"to_fmu: model {name!r} has inputs that switch in time ({', '.join(map(str, switches[:3]))}"
                         f"{', ...' if len(switches) > 3 else ''}), which need time events, not in FMUs yet; give "
                         f"smooth signals (constants, sin(t), ...), or give the source a number: it is then an FMU input that the "
                         f"importing tool switches; or run it with Model.simulate.")
    if len(eq.velocity_constraints):
        owners = sorted(set(eq.velocity_owners))
        raise ModelError(f"to_fmu: model {name!r} has constraints on velocities (nonholonomic: "
                         f"{', '.join(map(repr, owners))}), not in FMUs yet: run it with Model.simulate.")
    if len(eq.constraints):
        owners = sorted({o or "a closed loop of joints" for o in eq.constraint_owners})
        raise ModelError(f"to_fmu: model {name!r} has constraints on positions ({', '.join(map(repr, owners))}), "
                         f"whose consistent start an FMU does not check yet: build it with coordinates that close "
                         f"the loop by themselves, or run it with Model.simulate.")


def _platform() -> tuple[str, str]:
    """The FMI 2.0 platform folder and library suffix of this machine."""
    bits = struct.calcsize("P") * 8
    if sys.platform.startswith("win"):
        return f"win{bits}", ".dll"
    if sys.platform == "darwin":
        return f"darwin{bits}", ".dylib"
    return f"linux{bits}", ".so"


def _number(x: float, what: str) -> str:
    """``x`` as a C and XML number (17 significant digits), refusing what is not finite."""
    if not math.isfinite(x):
        raise ModelError(f"to_fmu: {what} is {x}, and an FMU's start values must be finite numbers; give a finite one.")
    return repr(float(x))


class _Variables:
    """The FMU's variables in order (value reference = index): states, their derivatives, parameters."""

    def __init__(self, model, numeric, y0):
        eq = numeric.eq
        self.states = [*eq.names, *(f"{eq.names[i]}'" for i in eq.inertial)]
        units = [coordinate_unit(n) for n in eq.names]
        self.state_units = [*units, *(f"{units[i]}/s" if units[i] else "" for i in eq.inertial)]
        self.rate_units = self._rates(eq, units)
        self.start = [_number(float(v), f"the start value of {n!r}") for n, v in zip(self.states, y0)]
        self.symbols = tuple(sorted(numeric.values, key=sp.default_sort_key))
        self.parameters = list(dict.fromkeys(s.name for s in self.symbols))  # one variable per name
        values = {s.name: float(numeric.values[s]) for s in self.symbols}
        self.values = [_number(values[p], f"parameter {p!r}") for p in self.parameters]
        self.slots = [self.parameters.index(s.name) for s in self.symbols]  # the variable of each P[k]
        self.owners = [model._declared_unit(p) for p in self.parameters]
        self.inputs = _inputs(model, self.parameters, self.owners)

    @staticmethod
    def _rates(eq, units):
        """Units of the derivatives: of a coordinate with inertia, its rate; of its rate, its acceleration; of a
        first-order coordinate, its rate."""
        rate = [f"{u}/s" if u else "" for u in units]
        return [*rate, *(f"{units[i]}/s²" if units[i] else "" for i in eq.inertial)]

    @property
    def nx(self) -> int:
        return len(self.states)


def _inputs(model, parameters: list[str], owners: list[tuple[str, str, str]]) -> set[str]:
    """The parameters that are the FMU's inputs: the scalar signal of a source or load given as a number (``E`` of a
    voltage source, ``F`` of a force, ``tau`` of a torque) that the equations read only as its present value.

    That is decided on the equations of a copy of the model in which each such signal is its value plus the rate of
    an input function ``w`` (:func:`lagrangian.derivation.assembly.driven`): an input is one whose ``w`` enters
    only as ``ẇ``.  A prescribed motion (its rates enter too) and a source whose integral fixes a coordinate
    (``w`` itself enters: a voltage source in node fluxes) stay tunable parameters, whose value is held."""
    chosen = {}
    for p, (owner, pname, _) in zip(parameters, owners):
        comp = model.components.get(owner)
        spec = comp.parameters.get(pname) if comp is not None else None
        if spec is not None and spec.shape == "signal" and not isinstance(comp.params.get(pname), sp.MatrixBase):
            chosen[owner] = (pname, None, p)
    if not chosen:
        return set()
    twin, functions = driven(model, chosen)
    g = twin.eq._generic
    exprs = [*g["M"], *g["f"], *g["constraints"], *g["velocity_constraints"]]
    found = set()
    for name, w in functions.items():
        u = sp.Dummy("u")
        rest = [e.xreplace({sp.Derivative(w(t), t): u}) for e in exprs if e.has(w)]
        if rest and not any(e.has(w) for e in rest):
            found.add(chosen[name][2])
    return found


def _description(model, v: _Variables, guid: str, identifier: str, source_name: str, kind: str) -> str:
    """``modelDescription.xml``."""
    units: dict[str, tuple[int, ...]] = {}

    def unit(text: str) -> str:
        found = _unit_exponents(text) if text else None
        if found is None:
            return ""
        units[found[0]] = found[1]
        return f' unit="{xml_text(found[0])}"'

    rows = []
    for i, (name, start) in enumerate(zip(v.states, v.start)):
        rows.append(f'    <ScalarVariable name="{xml_text(name)}" valueReference="{i}" causality="output" '
                    f'variability="continuous" initial="exact" description="state">'
                    f'<Real start="{start}"{unit(v.state_units[i])}/></ScalarVariable>')
    for i, name in enumerate(v.states):
        rows.append(f'    <ScalarVariable name="der({xml_text(name)})" valueReference="{v.nx + i}" causality="local" '
                    f'variability="continuous" initial="calculated"><Real derivative="{i + 1}"'
                    f'{unit(v.rate_units[i])}/></ScalarVariable>')
    for j, (name, value) in enumerate(zip(v.parameters, v.values)):
        owner, pname, declared = v.owners[j]
        about = f' description="{xml_text(f"{pname} of {owner}")}"' if owner != model.name else ""
        role = ('causality="input" variability="continuous"' if name in v.inputs else
                'causality="parameter" variability="tunable" initial="exact"')
        rows.append(f'    <ScalarVariable name="{xml_text(name)}" valueReference="{2 * v.nx + j}" {role}{about}>'
                    f'<Real start="{value}"{unit(declared)}/></ScalarVariable>')
    unit_rows = [f'    <Unit name="{xml_text(name)}"><BaseUnit '
                 + " ".join(f'{b}="{e}"' for b, e in zip(_BASE, exps) if e) + "/></Unit>"
                 for name, exps in sorted(units.items())]
    outputs = "".join(f'\n      <Unknown index="{i + 1}"/>' for i in range(v.nx))
    element, special = ("ModelExchange", 'completedIntegratorStepNotNeeded="true" ') if kind == "model-exchange" else (
        "CoSimulation", 'canHandleVariableCommunicationStepSize="true" canInterpolateInputs="false" '
                        'maxOutputDerivativeOrder="0" canRunAsynchronuously="false" ')
    derivatives = "".join(f'\n      <Unknown index="{v.nx + i + 1}"/>' for i in range(v.nx))
    return "\n".join([
        '<?xml version="1.0" encoding="UTF-8"?>',
        f'<fmiModelDescription fmiVersion="2.0" modelName="{xml_text(model.name)}" guid="{guid}" '
        f'description="{xml_text(model.name)}: coordinates {xml_text(", ".join(model.eq.names))}" '
        f'generationTool="lagrangian" variableNamingConvention="flat" numberOfEventIndicators="0">',
        f'  <{element} modelIdentifier="{identifier}" needsExecutionTool="false" {special}'
        f'canBeInstantiatedOnlyOncePerProcess="false" canNotUseMemoryManagementFunctions="true" '
        f'canGetAndSetFMUstate="false" canSerializeFMUstate="false" providesDirectionalDerivative="false">',
        f'    <SourceFiles><File name="{source_name}"/></SourceFiles>',
        f"  </{element}>",
        *(["  <UnitDefinitions>", *unit_rows, "  </UnitDefinitions>"] if unit_rows else []),
        '  <DefaultExperiment startTime="0.0" stopTime="10.0" tolerance="1e-09"/>',
        "  <ModelVariables>",
        *rows,
        "  </ModelVariables>",
        "  <ModelStructure>",
        *([f"    <Outputs>{outputs}\n    </Outputs>", f"    <Derivatives>{derivatives}\n    </Derivatives>",
           f"    <InitialUnknowns>{derivatives}\n    </InitialUnknowns>"] if v.nx else []),
        "  </ModelStructure>",
        "</fmiModelDescription>",
        "",
    ])


# -- the C ----------------------------------------------------------------------------------------------------------
_FUNCTIONS = (
    "fmi2GetTypesPlatform", "fmi2GetVersion", "fmi2SetDebugLogging", "fmi2Instantiate", "fmi2FreeInstance",
    "fmi2SetupExperiment", "fmi2EnterInitializationMode", "fmi2ExitInitializationMode", "fmi2Terminate", "fmi2Reset",
    "fmi2GetReal", "fmi2GetInteger", "fmi2GetBoolean", "fmi2GetString", "fmi2SetReal", "fmi2SetInteger",
    "fmi2SetBoolean", "fmi2SetString", "fmi2GetFMUstate", "fmi2SetFMUstate", "fmi2FreeFMUstate",
    "fmi2SerializedFMUstateSize", "fmi2SerializeFMUstate", "fmi2DeSerializeFMUstate", "fmi2GetDirectionalDerivative",
    "fmi2EnterEventMode", "fmi2NewDiscreteStates", "fmi2EnterContinuousTimeMode", "fmi2CompletedIntegratorStep",
    "fmi2SetTime", "fmi2SetContinuousStates", "fmi2GetDerivatives", "fmi2GetEventIndicators",
    "fmi2GetContinuousStates", "fmi2GetNominalsOfContinuousStates", "fmi2SetRealInputDerivatives",
    "fmi2GetRealOutputDerivatives", "fmi2DoStep", "fmi2CancelStep", "fmi2GetStatus", "fmi2GetRealStatus",
    "fmi2GetIntegerStatus", "fmi2GetBooleanStatus", "fmi2GetStringStatus",
)

# The FMI 2.0 types (fmi2TypesPlatform.h, fmi2FunctionTypes.h of the standard), as far as the functions need them.
_FMI2_TYPES = r"""
typedef void *fmi2Component;
typedef void *fmi2ComponentEnvironment;
typedef void *fmi2FMUstate;
typedef unsigned int fmi2ValueReference;
typedef double fmi2Real;
typedef int fmi2Integer;
typedef int fmi2Boolean;
typedef char fmi2Char;
typedef const fmi2Char *fmi2String;
typedef char fmi2Byte;
#define fmi2True 1
#define fmi2False 0
typedef enum { fmi2OK, fmi2Warning, fmi2Discard, fmi2Error, fmi2Fatal, fmi2Pending } fmi2Status;
typedef enum { fmi2ModelExchange, fmi2CoSimulation } fmi2Type;
typedef enum { fmi2DoStepStatus, fmi2PendingStatus, fmi2LastSuccessfulTime, fmi2Terminated } fmi2StatusKind;
typedef void (*fmi2CallbackLogger)(fmi2ComponentEnvironment, fmi2String, fmi2Status, fmi2String, fmi2String, ...);
typedef void *(*fmi2CallbackAllocateMemory)(size_t, size_t);
typedef void (*fmi2CallbackFreeMemory)(void *);
typedef void (*fmi2StepFinished)(fmi2ComponentEnvironment, fmi2Status);
typedef struct {
    const fmi2CallbackLogger logger;
    const fmi2CallbackAllocateMemory allocateMemory;
    const fmi2CallbackFreeMemory freeMemory;
    const fmi2StepFinished stepFinished;
    const fmi2ComponentEnvironment componentEnvironment;
} fmi2CallbackFunctions;
typedef struct {
    fmi2Boolean newDiscreteStatesNeeded;
    fmi2Boolean terminateSimulation;
    fmi2Boolean nominalsOfContinuousStatesChanged;
    fmi2Boolean valuesOfContinuousStatesChanged;
    fmi2Boolean nextEventTimeDefined;
    fmi2Real nextEventTime;
} fmi2EventInfo;

#if defined(_WIN32)
#define FMI2_EXPORT __declspec(dllexport)
#elif defined(__GNUC__)
#define FMI2_EXPORT __attribute__((visibility("default")))
#else
#define FMI2_EXPORT
#endif
"""

# The instance and the fmi2 functions.  States x = (q, q'_inertial), value references: x (0 .. NX-1), der(x)
# (NX .. 2 NX - 1), parameters (2 NX ..); PSLOT[k] is the parameter variable whose value is P[k] of lg_rhs.
_FMI2_BODY = r"""
#define NX (NQ + NI)
#define NVR (2 * NX + NV)
#define DIM(n) ((n) > 0 ? (n) : 1)

typedef struct {
    fmi2CallbackLogger logger;
    fmi2ComponentEnvironment env;
    char *name;
    int logging, valid;
    double t, rtol;
    double x[DIM(NX)], dx[DIM(NX)], V[DIM(NV)], P[DIM(NP)];
} Instance;

static void say(Instance *c, fmi2Status status, const char *message) {
    if (c && c->logger) c->logger(c->env, c->name ? c->name : "", status, status == fmi2OK ? "logAll" : "logStatusError",
                                  message);
}

static void set_defaults(Instance *c) {
    c->t = 0.0;
    c->rtol = 1e-9;
    c->valid = 0;
    for (int i = 0; i < NX; i++) c->x[i] = X0[i];
    for (int j = 0; j < NV; j++) c->V[j] = V0[j];
    for (int k = 0; k < NP; k++) c->P[k] = V0[PSLOT[k]];
}

/* The derivatives at (t, x), computed once per change of t, x or a parameter. */
static fmi2Status evaluate(Instance *c) {
    if (c->valid) return fmi2OK;
    int rc = lg_rhs(c->P, c->t, c->x, c->dx);
    if (rc) {
        char text[200];
        snprintf(text, sizeof text, "the derivatives cannot be computed at t=%.17g: %s", c->t,
                 rc == 1 ? "the mass matrix is singular there" : rc == 2 ? "they are not finite there (a singular "
                 "configuration, or a diverging solution)" : "out of memory");
        say(c, fmi2Error, text);
        return fmi2Error;
    }
    c->valid = 1;
    return fmi2OK;
}

static fmi2Status unknown(Instance *c, const char *what, fmi2ValueReference vr) {
    char text[160];
    snprintf(text, sizeof text, "%s: there is no variable with value reference %u of that type", what, vr);
    say(c, fmi2Error, text);
    return fmi2Error;
}

static fmi2Status unsupported(fmi2Component c, const char *what) {
    char text[200];
    snprintf(text, sizeof text, "%s is not supported by this FMU (see its modelDescription.xml)", what);
    say((Instance *)c, fmi2Error, text);
    return fmi2Error;
}

FMI2_EXPORT const char *fmi2GetTypesPlatform(void) { return "default"; }
FMI2_EXPORT const char *fmi2GetVersion(void) { return "2.0"; }

FMI2_EXPORT fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                                           const fmi2String categories[]) {
    (void)nCategories; (void)categories;
    ((Instance *)c)->logging = loggingOn;
    return fmi2OK;
}

FMI2_EXPORT fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                                          fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                                          fmi2Boolean visible, fmi2Boolean loggingOn) {
    (void)fmuResourceLocation; (void)visible;
    Instance probe = {0};
    if (functions) { probe.logger = functions->logger; probe.env = functions->componentEnvironment; }
    probe.name = (char *)(instanceName ? instanceName : "");
    if ((int)fmuType != KIND) {
        say(&probe, fmi2Error, KIND == fmi2ModelExchange ? "fmi2Instantiate: this FMU is for model exchange only"
                                                         : "fmi2Instantiate: this FMU is for co-simulation only");
        return NULL;
    }
    if (!fmuGUID || strcmp(fmuGUID, GUID) != 0) {
        say(&probe, fmi2Error, "fmi2Instantiate: the GUID is not this FMU's (its modelDescription.xml and binary differ)");
        return NULL;
    }
    Instance *c = calloc(1, sizeof(Instance));
    size_t length = strlen(probe.name);
    char *name = malloc(length + 1);
    if (!c || !name) {
        free(c); free(name);
        say(&probe, fmi2Error, "fmi2Instantiate: out of memory");
        return NULL;
    }
    memcpy(name, probe.name, length + 1);
    c->logger = probe.logger;
    c->env = probe.env;
    c->name = name;
    c->logging = loggingOn;
    set_defaults(c);
    return c;
}

FMI2_EXPORT void fmi2FreeInstance(fmi2Component c) {
    if (!c) return;
    free(((Instance *)c)->name);
    free(c);
}

FMI2_EXPORT fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                                           fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    (void)stopTimeDefined; (void)stopTime;
    if (toleranceDefined && tolerance > 0) ((Instance *)c)->rtol = tolerance;
    ((Instance *)c)->t = startTime;
    ((Instance *)c)->valid = 0;
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2EnterInitializationMode(fmi2Component c) { (void)c; return fmi2OK; }
FMI2_EXPORT fmi2Status fmi2ExitInitializationMode(fmi2Component c) { return evaluate((Instance *)c); }
FMI2_EXPORT fmi2Status fmi2Terminate(fmi2Component c) { (void)c; return fmi2OK; }
FMI2_EXPORT fmi2Status fmi2Reset(fmi2Component c) { set_defaults((Instance *)c); return fmi2OK; }

FMI2_EXPORT fmi2Status fmi2GetReal(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                                   fmi2Real value[]) {
    Instance *c = component;
    for (size_t i = 0; i < nvr; i++) {
        const fmi2ValueReference r = vr[i];
        if (r < NX) value[i] = c->x[r];
        else if (r < 2 * NX) {
            if (evaluate(c) != fmi2OK) return fmi2Error;
            value[i] = c->dx[r - NX];
        } else if (r < NVR) value[i] = c->V[r - 2 * NX];
        else return unknown(c, "fmi2GetReal", r);
    }
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2SetReal(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                                   const fmi2Real value[]) {
    Instance *c = component;
    for (size_t i = 0; i < nvr; i++) {
        const fmi2ValueReference r = vr[i];
        if (r < NX) c->x[r] = value[i];
        else if (r < 2 * NX) {
            say(c, fmi2Error, "fmi2SetReal: a derivative der(...) is computed by the FMU and cannot be set");
            return fmi2Error;
        } else if (r < NVR) {
            c->V[r - 2 * NX] = value[i];
            for (int k = 0; k < NP; k++) if (PSLOT[k] == (int)(r - 2 * NX)) c->P[k] = value[i];
        } else return unknown(c, "fmi2SetReal", r);
        c->valid = 0;
    }
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[]) {
    (void)value; return nvr ? unknown(c, "fmi2GetInteger", vr[0]) : fmi2OK;
}
FMI2_EXPORT fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[]) {
    (void)value; return nvr ? unknown(c, "fmi2GetBoolean", vr[0]) : fmi2OK;
}
FMI2_EXPORT fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[]) {
    (void)value; return nvr ? unknown(c, "fmi2GetString", vr[0]) : fmi2OK;
}
FMI2_EXPORT fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[]) {
    (void)value; return nvr ? unknown(c, "fmi2SetInteger", vr[0]) : fmi2OK;
}
FMI2_EXPORT fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[]) {
    (void)value; return nvr ? unknown(c, "fmi2SetBoolean", vr[0]) : fmi2OK;
}
FMI2_EXPORT fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[]) {
    (void)value; return nvr ? unknown(c, "fmi2SetString", vr[0]) : fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state) {
    (void)state; return unsupported(c, "fmi2GetFMUstate");
}
FMI2_EXPORT fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state) {
    (void)state; return unsupported(c, "fmi2SetFMUstate");
}
FMI2_EXPORT fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state) {
    (void)state; return unsupported(c, "fmi2FreeFMUstate");
}
FMI2_EXPORT fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t *size) {
    (void)state; (void)size; return unsupported(c, "fmi2SerializedFMUstateSize");
}
FMI2_EXPORT fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state, fmi2Byte bytes[], size_t size) {
    (void)state; (void)bytes; (void)size; return unsupported(c, "fmi2SerializeFMUstate");
}
FMI2_EXPORT fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte bytes[], size_t size, fmi2FMUstate *state) {
    (void)state; (void)bytes; (void)size; return unsupported(c, "fmi2DeSerializeFMUstate");
}
FMI2_EXPORT fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[],
                                                    size_t nUnknown, const fmi2ValueReference vKnown_ref[],
                                                    size_t nKnown, const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    (void)vUnknown_ref; (void)nUnknown; (void)vKnown_ref; (void)nKnown; (void)dvKnown; (void)dvUnknown;
    return unsupported(c, "fmi2GetDirectionalDerivative");
}

FMI2_EXPORT fmi2Status fmi2EnterEventMode(fmi2Component c) { (void)c; return fmi2OK; }
FMI2_EXPORT fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *info) {
    (void)c;
    info->newDiscreteStatesNeeded = fmi2False;
    info->terminateSimulation = fmi2False;
    info->nominalsOfContinuousStatesChanged = fmi2False;
    info->valuesOfContinuousStatesChanged = fmi2False;
    info->nextEventTimeDefined = fmi2False;
    info->nextEventTime = 0.0;
    return fmi2OK;
}
FMI2_EXPORT fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) { (void)c; return fmi2OK; }
FMI2_EXPORT fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                                   fmi2Boolean *enterEventMode, fmi2Boolean *terminateSimulation) {
    (void)c; (void)noSetFMUStatePriorToCurrentPoint;
    *enterEventMode = fmi2False;
    *terminateSimulation = fmi2False;
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2SetTime(fmi2Component c, fmi2Real time) {
    ((Instance *)c)->t = time;
    ((Instance *)c)->valid = 0;
    return fmi2OK;
}

static fmi2Status sized(Instance *c, const char *what, size_t n, size_t expected) {
    if (n == expected) return fmi2OK;
    char text[160];
    snprintf(text, sizeof text, "%s: %lu values given, the FMU has %lu", what, (unsigned long)n,
             (unsigned long)expected);
    say(c, fmi2Error, text);
    return fmi2Error;
}

FMI2_EXPORT fmi2Status fmi2SetContinuousStates(fmi2Component component, const fmi2Real x[], size_t nx) {
    Instance *c = component;
    if (sized(c, "fmi2SetContinuousStates", nx, NX) != fmi2OK) return fmi2Error;
    for (int i = 0; i < NX; i++) c->x[i] = x[i];
    c->valid = 0;
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2GetDerivatives(fmi2Component component, fmi2Real derivatives[], size_t nx) {
    Instance *c = component;
    if (sized(c, "fmi2GetDerivatives", nx, NX) != fmi2OK || evaluate(c) != fmi2OK) return fmi2Error;
    for (int i = 0; i < NX; i++) derivatives[i] = c->dx[i];
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real eventIndicators[], size_t ni) {
    (void)eventIndicators;
    return sized(c, "fmi2GetEventIndicators", ni, 0);
}

FMI2_EXPORT fmi2Status fmi2GetContinuousStates(fmi2Component component, fmi2Real x[], size_t nx) {
    Instance *c = component;
    if (sized(c, "fmi2GetContinuousStates", nx, NX) != fmi2OK) return fmi2Error;
    for (int i = 0; i < NX; i++) x[i] = c->x[i];
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x_nominal[], size_t nx) {
    if (sized(c, "fmi2GetNominalsOfContinuousStates", nx, NX) != fmi2OK) return fmi2Error;
    for (int i = 0; i < NX; i++) x_nominal[i] = 1.0;
    return fmi2OK;
}
"""


# Co-simulation: each communication step is one run of the DOP853 loop (Model.simulate's default method) from the
# state reached, rtol the experiment's tolerance (else 1e-9, as simulate's) and atol = rtol / 1000.
_CS_BODY = r"""
FMI2_EXPORT fmi2Status fmi2DoStep(fmi2Component component, fmi2Real currentCommunicationPoint,
                                  fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    Instance *c = component;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!(communicationStepSize > 0)) {
        say(c, fmi2Error, "fmi2DoStep: the communication step size must be positive");
        return fmi2Error;
    }
    double t1 = currentCommunicationPoint + communicationStepSize;
    double *Y = malloc(sizeof(double) * (2 * DIM(NX) + 1));
    long counts[3] = {0, 0, 0};
    if (!Y) { say(c, fmi2Error, "fmi2DoStep: out of memory"); return fmi2Error; }
    int rc = lg_dop853(lg_rhs, c->P, NX, currentCommunicationPoint, t1, c->x, 1, &t1, c->rtol, c->rtol * 1e-3, 1e300,
                       0.0, 0.0, NULL, Y, counts, Y + DIM(NX));
    if (rc) {
        char text[240];
        snprintf(text, sizeof text, "fmi2DoStep: the step from t=%.17g to %.17g failed at t=%.17g: %s",
                 currentCommunicationPoint, t1, Y[DIM(NX)], rc == 1 ? "the mass matrix is singular there" :
                 rc == 2 ? "the derivatives are not finite there" : rc == 3 ? "the step size fell below the "
                 "resolution of t (stiff or singular there)" : rc == 4 ? "the state diverged" : "out of memory");
        free(Y);
        say(c, fmi2Error, text);
        return fmi2Error;
    }
    for (int i = 0; i < NX; i++) c->x[i] = Y[i];
    free(Y);
    c->t = t1;
    c->valid = 0;
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                                   const fmi2Integer order[], const fmi2Real value[]) {
    (void)order; (void)value; return nvr ? unknown(c, "fmi2SetRealInputDerivatives", vr[0]) : fmi2OK;
}
FMI2_EXPORT fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                                    const fmi2Integer order[], fmi2Real value[]) {
    (void)order; (void)value; return nvr ? unsupported(c, "fmi2GetRealOutputDerivatives") : fmi2OK;
}
FMI2_EXPORT fmi2Status fmi2CancelStep(fmi2Component c) { return unsupported(c, "fmi2CancelStep"); }
FMI2_EXPORT fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    (void)c; (void)s; (void)value; return fmi2Discard;
}
FMI2_EXPORT fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    if (s != fmi2LastSuccessfulTime) return fmi2Discard;
    *value = ((Instance *)c)->t;
    return fmi2OK;
}
FMI2_EXPORT fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    (void)c; (void)s; (void)value; return fmi2Discard;
}
FMI2_EXPORT fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    (void)c;
    if (s != fmi2Terminated) return fmi2Discard;
    *value = fmi2False;
    return fmi2OK;
}
FMI2_EXPORT fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    (void)c; (void)s; (void)value; return fmi2Discard;
}
"""


def _c_source(model, v: _Variables, guid: str, kind: str) -> str:
    """The FMU's one C file: the model's parametric native source, then the fmi2 functions."""
    try:
        native = parametric_source(model.eq, v.symbols)
    except _Unavailable as exc:
        raise ModelError(f"to_fmu: model {model.name!r} cannot be written as C: {exc}.") from None

    def table(values):
        return "{" + ", ".join(map(str, values or [0])) + "}"

    prefix = [f"#define {f} fmi2FullName({f})" for f in _FUNCTIONS]
    return "\n".join([
        c_comment(f"FMI 2.0 {kind}: model {model.name}; states {', '.join(v.states)}; "
                  f"parameters {', '.join(v.parameters)}."),
        "#include <math.h>", "#include <float.h>", "#include <stddef.h>", "#include <stdio.h>",
        "#include <stdlib.h>", "#include <string.h>",
        "#if defined(__GNUC__) && !defined(_WIN32)",
        "#pragma GCC visibility push(hidden)",  # the model's functions stay inside the library
        "#endif",
        native,
        "#if defined(__GNUC__) && !defined(_WIN32)",
        "#pragma GCC visibility pop",
        "#endif",
        _FMI2_TYPES,
        "/* Built into a static library with other FMUs: FMI2_FUNCTION_PREFIX prefixes the fmi2 functions. */",
        "#ifdef FMI2_FUNCTION_PREFIX",
        "#define fmi2Paste(a, b) a ## b",
        "#define fmi2PasteB(a, b) fmi2Paste(a, b)",
        "#define fmi2FullName(name) fmi2PasteB(FMI2_FUNCTION_PREFIX, name)",
        *prefix,
        "#endif",
        f"#define NV {len(v.parameters)}",
        f"static const int KIND = {KINDS.index(kind)};  /* fmi2ModelExchange 0, fmi2CoSimulation 1 */",
        f'static const char GUID[] = "{guid}";',
        f"static const double X0[] = {table(v.start)};",
        f"static const double V0[] = {table(v.values)};",
        f"static const int PSLOT[] = {table(v.slots)};",
        _FMI2_BODY,
        *(["#if defined(__GNUC__) && !defined(_WIN32)", "#pragma GCC visibility push(hidden)", "#endif", _LOOPS,
           dop853_source(), "#if defined(__GNUC__) && !defined(_WIN32)", "#pragma GCC visibility pop", "#endif",
           _CS_BODY] if kind == "co-simulation" else []),
    ])


def _guid(*parts: str) -> str:
    """A GUID from the FMU's content, so that the same model with the same values exports the same FMU (and the
    compiled-code cache builds its library once)."""
    digest = hashlib.sha256("\n".join(parts).encode()).digest()
    return "{" + str(uuid.UUID(bytes=digest[:16], version=4)) + "}"


def export(model, path, kind: str = "model-exchange", *, initial=None, velocity=None, params=None,
           identifier: str | None = None, **unknown) -> Path:
    """Write ``model`` as an FMI 2.0 FMU to ``path`` (see :meth:`lagrangian.Model.to_fmu`); returns the path."""
    if unknown:
        raise ModelError(f"to_fmu: unknown argument {next(iter(unknown))!r}; it takes path, kind, model_identifier, "
                         f"initial, velocity and params.")
    _refuse(model, kind)
    identifier = model_identifier(model.name, identifier)
    numeric = model.numeric(params)
    y0, _ = initial_state(model.eq, dict(initial or {}), dict(velocity or {}), warn=False)
    check_start(numeric, model.name, 0.0, y0, params=params)
    variables = _Variables(model, numeric, y0)
    cc = compiler()
    if cc is None:
        raise ModelError("to_fmu builds the FMU's binary with a C compiler, and none was found (none of cc, gcc, "
                         "clang on the PATH, or LAGRANGIAN_CC): install one.")
    source_name = f"{identifier}.c"
    draft = _c_source(model, variables, "{GUID}", kind) + _description(model, variables, "{GUID}", identifier, source_name,
                                                                 kind)
    guid = _guid(draft)
    source = _c_source(model, variables, guid, kind)
    description = _description(model, variables, guid, identifier, source_name, kind)
    directory, _ = _cache()
    key = "fmu-" + _key(source, cc)
    try:
        binary = _libraries(directory, {"fmu": (key, source)}, cc)["fmu"].data  # the bytes checked and loaded
    except (_Unavailable, OSError) as exc:
        raise ModelError(f"to_fmu: the FMU's binary could not be built in {directory}: {exc}.") from None
    platform, suffix = _platform()
    target = Path(os.fspath(path))
    if target.is_dir():
        raise ModelError(f"to_fmu: {str(target)!r} is a directory; give a file name, such as "
                         f"{str(target / (identifier + '.fmu'))!r}.")
    try:
        fd, tmp = tempfile.mkstemp(dir=target.parent if str(target.parent) else ".", prefix=".fmu-", suffix=".tmp")
    except OSError as exc:
        raise ModelError(f"to_fmu: cannot write in {str(target.parent)!r} ({exc.strerror}); give a path in a "
                         f"writable directory.") from None
    try:
        with os.fdopen(fd, "wb") as fh, zipfile.ZipFile(fh, "w", zipfile.ZIP_DEFLATED) as archive:
            archive.writestr("modelDescription.xml", description)
            archive.writestr(f"binaries/{platform}/{identifier}{suffix}", binary)
            archive.writestr(f"sources/{source_name}", source)
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return target
