"""The Bode plot of an imported ladder filter, checked against its closed form and ngspice.
========================================================================================

``butterworth.cir`` is a fifth-order Butterworth low-pass LC ladder between
two 50 Ω terminations, cutoff 1 kHz, with an ``.ac dec 50 10 100k`` line and
an ``AC 1`` source.  Read as a netlist, its small-signal response at every
node follows from the Lagrangian of the circuit; at the load it is

    ``|H(f)|`` = ½ / √(1 + (f/fc)^10),

−3 dB below the passband's ½ at fc and falling 100 dB per decade beyond.
The same deck runs through ngspice's own AC analysis.

Run: .venv/bin/python examples/ladder_filter_bode.py [--deck examples/butterworth.cir] [--out ladder_bode.png]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import numpy as np

from lagrangian.ac import compare_ac_with_ngspice
from lagrangian.netlist import read_netlist_file
from lagrangian.spice import NgspiceMissingError

HERE = Path(globals().get("__file__", "ladder_filter_bode.py")).resolve().parent  # (the gallery runs it in examples/)
FC = 1000.0


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").partition("\n")[0])
    parser.add_argument("--deck", default=str(HERE / "butterworth.cir"), help="the netlist to read")
    parser.add_argument("--out", default="ladder_bode.png", help="where to write the Bode chart (PNG)")
    args = parser.parse_args()

    net = read_netlist_file(args.deck)
    print(f"{net.title}: {len(net.model.components)} elements, AC sources {net.ac_sources}, sweep {net.ac}")
    resp = net.frequency_response(outputs=["v(n1)", "v(n2)", "v(n3)"])
    f = resp.frequencies
    closed = 0.5 / np.sqrt(1 + (f / FC) ** 10)
    load = np.abs(resp["v(n3)"])
    print(f"max |H| / closed form − 1 at the load: {np.max(np.abs(load / closed - 1)):.2e}")
    at_fc = np.abs(net.frequency_response(outputs=["v(n3)"], frequencies=[FC])["v(n3)"][0])
    print(f"|H(fc)| = {at_fc:.12f} (½/√2 = {0.5 / np.sqrt(2):.12f}): {20 * np.log10(at_fc / 0.5):.9f} dB from the passband")
    decade = np.abs(net.frequency_response(outputs=["v(n3)"], frequencies=[10 * FC, 100 * FC])["v(n3)"])
    print(f"roll-off from 10 fc to 100 fc: {20 * np.log10(decade[1] / decade[0]):.4f} dB per decade (order 5: −100)")
    try:
        cmp = compare_ac_with_ngspice(net, outputs=["v(n1)", "v(n2)", "v(n3)"])
    except NgspiceMissingError as exc:
        print(f"ngspice skipped: {exc}")
    else:
        print(cmp.table())
        print(f"ngspice vs ours: worst relative difference {cmp.worst_rel:.2e}")
    fig = resp.plot("bode", path=args.out)
    fig.axes[0].semilogx(f, 20 * np.log10(closed), "k:", lw=1, label="closed form at the load")
    fig.axes[0].set_ylim(-120, 5)
    fig.axes[0].legend(fontsize=8)
    fig.savefig(args.out, dpi=110)
    print(f"chart written to {args.out}")


if __name__ == "__main__":
    main()
