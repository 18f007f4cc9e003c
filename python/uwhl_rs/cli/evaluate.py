"""``uwhl evaluate MANIFEST``: the paper's metrics on annotated photos,
beside the baselines (``uwhl_rs.evaluate``, docs/EVALUATE.md)."""

from __future__ import annotations

import argparse
import os
import time

import uwhl_rs

from .. import evaluate as ev
from ..errors import CommandError, ManifestError, describe, kind_of
from ..console import Console
from .parser import method_kwargs, water_types

__all__ = ["run"]


def _fmt(x) -> str:
    return "" if x is None else f"{x:.4f}"


def _signed(x) -> str:
    return "?" if x is None else f"{x:+.2f}"


def run(a: argparse.Namespace, console: Console) -> int:
    """``uwhl evaluate``: the exit status (docs/CLI.md's codes)."""
    types = water_types(a.water_types)
    kwargs = {k: v for k, v in method_kwargs(a, skip=("method",)).items() if v is not None}
    if types is not None:
        kwargs["water_types"] = types
    def about_manifest(message: str) -> str:
        # the line names the manifest once (the reader's messages start with its path)
        return message.removeprefix(f"{a.manifest}: ")

    try:
        entries, problems = ev.load_manifest(a.manifest)
    except ManifestError as e:
        raise CommandError(about_manifest(str(e)), e.kind, a.manifest) from e
    # the images the manifest lists, the entries that cannot be evaluated among them
    listed = len(entries) + sum(1 for p in problems if p.startswith("images["))
    code = 0
    for p in problems:
        code = max(code, console.error("unreadable_input", about_manifest(p), a.manifest))
    results = []
    sections: dict[str, str] = {}
    methods = ev.report_methods(a.method, ev.METHODS)
    t0 = time.perf_counter()
    for k, entry in enumerate(entries, 1):
        t = time.perf_counter()
        try:
            r = ev.evaluate_entry(entry, a.method, a.mask_charts, **kwargs)
        except (Exception, MemoryError) as e:  # one entry's failure is its line; the others go on
            # the line is prefixed with the entry's label once, whether or not the error already named it
            text = describe(e, entry.path).removeprefix(f"{entry.label}: ")
            # named by its entry (a --json-errors line's input), which names the manifest's list
            code = max(code, console.error(kind_of(e), text, entry.label))
            problems.append(f"{entry.label}: {text}")
            continue
        # its part of the page now, then its full-size images go: memory does not grow with the manifest
        sections[r["image"]] = ev.image_section(r, entry, methods)
        for key in [k for k in r if k.startswith("_")]:
            del r[key]
        results.append(r)
        psi = [row["psi_deg"] for row in r["charts"] if row["method"] == r["method"]]
        rho = r["rho"].get(r["method"], {}).get("rho_B")
        ang = r["truth_angles"].get(r["method"], {}).get("median_deg")
        console.line(f"[{k}/{len(entries)}] {entry.label}: water type {r['water_type']}"
                     + (f", psi-bar {', '.join(f'{v:.1f}' for v in psi if v is not None)} deg" if psi else "")
                     + (f", rho {rho:.3f}" if rho is not None else "")
                     + (f", angle to truth {ang:.1f} deg" if ang is not None else "")
                     + f" ({time.perf_counter() - t:.1f} s)")
    try:
        parameters = {"method": a.method, "mask_charts": a.mask_charts,
                      **{k: v if not isinstance(v, tuple) else list(v) for k, v in kwargs.items()},
                      "profiles": {m: uwhl_rs.method_steps(**({**kwargs, "method": m} if m == a.method else {"method": m}))
                                   for m in ev.METHODS}}
        doc = ev.write_results(a.out, a.manifest, results, problems, parameters)
        ev.write_report(a.out, doc, results, entries, a.method, ev.METHODS, sections)
    except OSError as e:
        raise CommandError(describe(e), "write_failed", a.out) from e
    truth = any(v.get("images_with_truth") for m, v in doc["summary"].items() if m not in ev.SUMMARY_EXTRAS)
    # with a truth: the median over images of the per-image median angle, raw and after the best gains
    console.line()
    # the method column as wide as its longest name ("revised+distance", "type:9C"), columns aligned
    width = max([12] + [len(m) for m in doc["summary"] if m not in ev.SUMMARY_EXTRAS])
    console.line(f"{'method':<{width}} {'psi-bar':>8} {'rho t_B':>8}" + (f" {'truth':>8} {'gains':>8}" if truth else ""))
    for m, v in doc["summary"].items():
        if m in ev.SUMMARY_EXTRAS:
            continue
        ci = v.get("truth_median_deg_ci95")
        console.line(f"{m:<{width}} {_fmt(v['psi_deg']):>8} {_fmt(v['rho_B']):>8}"
                     + (f" {_fmt(v['truth_median_deg']):>8} {_fmt(v['truth_gain_median_deg']):>8}" if truth else "")
                     + (f"  95% {_fmt(ci[0])}-{_fmt(ci[1])}" if truth and ci else ""))
    for m, against in doc["summary"].get("paired", {}).items():
        for b, p in against.items():
            console.line(f"{m} - {b}: {_signed(p['difference_deg'])} deg "
                         f"(95% {_signed(p['low_deg'])} to {_signed(p['high_deg'])}), "
                         f"better on {p['better']}, worse on {p['worse']} of {p['images']} images")
    if "water_type" in doc["summary"]:
        for m, wt in doc["summary"]["water_type"].items():
            console.line(f"water type ({m}): {wt['exact']:.0%} exact, {wt['within_one']:.0%} within one step"
                         + (f", the true one plausible in {wt['plausible']:.0%}" if "plausible" in wt else ""))
    console.line(f"{len(results)} of {listed} images evaluated in {time.perf_counter() - t0:.1f} s; "
                 f"{os.path.join(a.out, 'report.html')}")
    return code
