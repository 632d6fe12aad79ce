"""Test faults in a measured record: saturated channels, spikes and gaps in the time column.

A fault wrecks a fit if left in: a load cell flat at its limit for hundreds of samples reports a force the model
can never match, and a spike in the measured velocity (the model's input) kicks its internal states. The fitting
and scoring path (:func:`~mrd_env.identification.prepare.prepare_record`) excludes every fault span found here
from the objective and the error measures by default, repairs single-sample spikes of the input channels (x, v)
by linear interpolation so they do not drive the model, and says so in a :class:`FaultsExcluded` warning.

Detection, per measured channel (stroke, velocity, force; the switched command channel sits at its extremes by
design and is not searched):

* **saturation** — the channel sits at its maximum or minimum over the record: either exactly (a clipped channel
  repeats its limit value; once ``clip_samples`` consecutive samples equal it, every sample at that value is a
  fault — a natural extreme is reached at one sample), or within ``saturation_tol`` × (the channel's range) for
  at least ``saturation_duration`` seconds (a noisy clip; a smooth turning point stays that close to its extreme
  3 ms for a 2 Hz sine, 13 ms for 0.5 Hz — a stroke held still at its extreme longer than 20 ms, as in a
  quasi-static test, is reported too: use ``faults="keep"`` for such tests);
* **spike** — a sample that departs from both neighbours in the same direction by more than ``spike_threshold``
  times the robust scale of the channel's sample-to-sample change (1.4826 × median absolute deviation); a step
  (the command switching, a force following it) departs from one neighbour only and is not a spike;
* **gap** — a time step longer than ``gap_factor`` × the median step;
* **run-away** — a test gone wrong as a whole (an actuator running away, its load cell pinned at the limit): the
  samples whose speed |ẋ| (measured, else dx/dt) exceeds ``runaway_factor`` times the record's median speed — far
  beyond the test's envelope: a random test peaks near 7 times its median speed, a sine at 1.4 times; on the NEES
  record at 8.8 times — chained with the saturation spans they touch, across gaps shorter than ``runaway_gap``
  (the run-away reverses through zero speed), form one segment when the chain holds both; it reaches back and on
  to the nearest samples at or below the median speed (where the motion left and rejoined the test's), and into
  an end of the record closer than a gap. The whole segment is a fault, not only its clipped samples: the motion
  that drove the load cell to its limit is no test either.

Then the pieces are joined into **segments** (``merge_gap``, default 0.1 s; 0 returns the pieces as found): a test
gone wrong shows as dozens of pieces (spikes, saturations, run-away spans) with short stretches between them that
are no test either. Faults less than ``merge_gap`` apart form one segment, and a segment reaches on (and back) to
where the motion rejoins the test: the first stretch of ``merge_gap`` seconds free of faults whose motion stays
within the test's range (speed at most ``runaway_factor`` times the record's median speed, the run-away threshold;
stroke inside the central 90 % of the strokes outside the faults, widened by its width on each side). With
no such stretch between a segment and an end of the record, the segment runs into that end: a run-away that never
rejoins the test is excluded to the end of the record. A segment of several pieces is one :class:`Fault` of kind
"run-away" if one of its pieces is a run-away, else "segment"; its ``parts`` are the pieces (spikes of the input
channels inside it are still repaired). A lone fault keeps its kind (widened, with itself as its part, where the
motion beside it is out of the test's range); with the test on both sides it stays as it was found.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..validation import check_scalar
from ..records import DamperRecord

__all__ = ["Fault", "FaultsExcluded", "find_faults", "fault_mask", "describe_faults"]



class FaultsExcluded(UserWarning):
    """Faults were found in a record and left out of a fit or an error measure."""


@dataclass(frozen=True)
class Fault:
    """One fault: ``kind`` ("saturation", "spike", "gap", "run-away" or "segment"), ``channel`` ("x", "v",
    "force" or "t"; a segment's channels joined by "+"), ``start`` and ``end`` (s, inclusive; the samples
    i0..i1); ``parts``: the faults found inside a segment (empty for a fault found as it is)."""

    kind: str
    channel: str
    start: float
    end: float
    i0: int
    i1: int
    parts: tuple = ()

    def __str__(self) -> str:
        what = ("run-away (speed far beyond the test's, with a saturated channel)" if self.kind == "run-away"
                else "segment of faults" if self.kind == "segment"
                else f"{self.kind} of {self.channel}")
        where = f"{what} at t = {self.start:.5g}"
        if self.i0 == self.i1:
            return f"{where} s (1 sample)"
        out = f"{where}–{self.end:.5g} s ({self.i1 - self.i0 + 1} samples"
        if self.parts:
            counts: dict[str, int] = {}
            for f in self.parts:
                counts[f.kind] = counts.get(f.kind, 0) + 1
            out += ": " + ", ".join(f"{k} {kind}{'s' if k > 1 else ''}" for kind, k in counts.items())
        return out + ")"


def _runs(flags: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) index of each run of True."""
    d = np.diff(np.r_[0, flags.astype(np.int8), 0])
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1))


def _merged(spans: list[tuple[int, int]]) -> list[tuple[int, int]]:
    """Overlapping (first, last) spans merged, in order."""
    out: list[list[int]] = []
    for i0, i1 in spans:
        if out and i0 <= out[-1][1] + 1:
            out[-1][1] = max(out[-1][1], i1)
        else:
            out.append([i0, i1])
    return [(a, b) for a, b in out]


def _measured(record: DamperRecord) -> dict[str, np.ndarray]:
    ch = {"x": record.x, "force": record.force}
    if record.v is not None:
        ch["v"] = record.v
    return ch


def find_faults(record: DamperRecord, *, saturation_duration: float = 0.02, saturation_tol: float = 1e-4,
                clip_samples: int = 5, spike_threshold: float = 20.0, gap_factor: float = 1.5,
                runaway_factor: float = 8.0, runaway_gap: float = 0.05, merge_gap: float = 0.1) -> list[Fault]:
    """The faults of ``record`` (see the module docstring), in time order, joined into segments where less than
    ``merge_gap`` seconds apart or where the motion does not rejoin the test between them (0: the pieces)."""
    saturation_duration = check_scalar("saturation_duration", saturation_duration, 0.0, lo_open=True, unit="s")
    saturation_tol = check_scalar("saturation_tol", saturation_tol, 0.0, 1.0, lo_open=True)
    clip_samples = check_scalar("clip_samples", clip_samples, 2.0)
    spike_threshold = check_scalar("spike_threshold", spike_threshold, 1.0, lo_open=True)
    gap_factor = check_scalar("gap_factor", gap_factor, 1.0, lo_open=True)
    runaway_factor = check_scalar("runaway_factor", runaway_factor, 1.0, lo_open=True)
    runaway_gap = check_scalar("runaway_gap", runaway_gap, 0.0, unit="s")
    merge_gap = check_scalar("merge_gap", merge_gap, 0.0, unit="s")
    t = record.t
    steps = np.diff(t)
    dt = float(np.median(steps))
    faults: list[Fault] = []

    def add(kind, channel, i0, i1):
        faults.append(Fault(kind, channel, float(t[i0]), float(t[i1]), int(i0), int(i1)))

    for i in np.flatnonzero(steps > gap_factor * dt):
        add("gap", "t", i, i + 1)
    min_run = max(3, int(np.ceil(saturation_duration / dt)))
    for name, a in _measured(record).items():
        hi, lo = float(a.max()), float(a.min())
        tol = saturation_tol * (hi - lo)
        if hi > lo:
            for level in (hi, lo):
                exact = _runs(np.abs(a - level) <= 1e-12 * (hi - lo))
                clipped = any(i1 - i0 + 1 >= clip_samples for i0, i1 in exact)
                near = [r for r in _runs(np.abs(a - level) <= tol) if r[1] - r[0] + 1 >= min_run]
                spans = sorted(set(near) | (set(exact) if clipped else set()))
                for i0, i1 in _merged(spans):
                    add("saturation", name, i0, i1)
        if a.size >= 5:
            d = np.diff(a)
            scale = 1.4826 * float(np.median(np.abs(d - np.median(d))))
            if scale > 0:
                dm, dp = a[1:-1] - a[:-2], a[1:-1] - a[2:]
                score = np.where(np.sign(dm) == np.sign(dp), np.minimum(np.abs(dm), np.abs(dp)), 0.0)
                for i in np.flatnonzero(score > spike_threshold * scale) + 1:
                    add("spike", name, i, i)
    speed = np.abs(record.velocity())
    typical = float(np.median(speed))
    saturated = [(f.i0, f.i1) for f in faults if f.kind == "saturation"]
    if typical > 0 and saturated:
        fast = _runs(speed > runaway_factor * typical)
        gap = int(round(runaway_gap / dt))
        calm = np.flatnonzero(speed <= typical)
        for i0, i1 in _chains(fast, saturated, gap):
            # from where the motion left the test's (the last calm sample before) to where it rejoined it
            before, after = calm[calm < i0], calm[calm > i1]
            i0 = before[-1] + 1 if before.size else 0
            i1 = after[0] - 1 if after.size else t.size - 1
            # a segment that stops short of an end of the record by less than a gap runs into it
            add("run-away", "v", 0 if i0 < gap else i0, t.size - 1 if t.size - 1 - i1 < gap else i1)
    faults.sort(key=lambda f: (f.i0, f.channel))
    if merge_gap == 0 or not faults:
        return faults
    return _segments(faults, t, _test_range(record.x, speed, faults, runaway_factor * typical), merge_gap)


def _test_range(x: np.ndarray, speed: np.ndarray, pieces: list[Fault], fast: float) -> np.ndarray:
    """The samples whose motion is the test's: speed at most ``fast`` (when positive) and stroke inside the central
    90 % of the strokes of the other such samples outside the faults ``pieces``, widened by its width on each
    side (a sine's ±3 amplitudes, a Gaussian stroke's ±4.9 standard deviations)."""
    ok = speed <= fast if fast > 0 else np.ones(x.size, dtype=bool)
    base = ok & ~fault_mask(x.size, pieces)
    lo, hi = np.percentile(x[base] if np.count_nonzero(base) >= 10 else x, [5.0, 95.0])
    return ok & (x >= lo - (hi - lo)) & (x <= hi + (hi - lo))


def _segments(pieces: list[Fault], t: np.ndarray, in_range: np.ndarray, merge_gap: float) -> list[Fault]:
    """The faults ``pieces`` (in order) joined into segments: less than ``merge_gap`` s apart, or with no stretch of
    ``merge_gap`` s of test between them (samples free of faults, speed in range: ``in_range``)."""
    n = t.size
    free = in_range & ~fault_mask(n, pieces)
    dt = float(np.median(np.diff(t)))
    g = max(1, int(np.ceil(merge_gap / dt - 1e-9)))
    normal = [(a, b) for a, b in _runs(free) if b - a + 1 >= g]  # stretches where the test goes on
    starts = np.array([a for a, _ in normal], dtype=np.int64)
    ends = np.array([b for _, b in normal], dtype=np.int64)
    spans: list[list[int]] = []
    for f in pieces:
        i0, i1 = f.i0, f.i1
        k = np.searchsorted(ends, i0)  # the first stretch ending at or after the fault: none lies before it
        i0 = int(ends[k - 1]) + 1 if k > 0 else 0  # back to the end of the last stretch of test, or the start
        k = np.searchsorted(starts, i1, side="right")  # the first stretch starting after the fault
        i1 = int(starts[k]) - 1 if k < starts.size else n - 1
        if spans and t[i0] - t[spans[-1][1]] < merge_gap:
            spans[-1][1] = max(spans[-1][1], i1)
        else:
            spans.append([i0, i1])
    out = []
    for i0, i1 in spans:
        parts = tuple(f for f in pieces if f.i0 >= i0 and f.i1 <= i1)
        if len(parts) == 1 and (parts[0].i0, parts[0].i1) == (i0, i1):
            out.append(parts[0])  # a lone fault with the test on both sides
            continue
        kind = parts[0].kind if len(parts) == 1 else \
            "run-away" if any(f.kind == "run-away" for f in parts) else "segment"
        channels = "+".join(dict.fromkeys(c for f in parts for c in f.channel.split("+")))
        out.append(Fault(kind, channels, float(t[i0]), float(t[i1]), int(i0), int(i1), parts))
    return out


def _chains(fast, saturated, gap: int) -> list[tuple[int, int]]:
    """The spans of chains of ``fast`` and ``saturated`` spans (each joined to the next across fewer than ``gap``
    samples) that hold at least one of each."""
    spans = sorted([(a, b, "fast") for a, b in fast] + [(a, b, "saturated") for a, b in saturated])
    chains: list[list] = []
    for i0, i1, what in spans:
        if chains and i0 <= chains[-1][1] + gap:
            chains[-1][1] = max(chains[-1][1], i1)
            chains[-1][2].add(what)
        else:
            chains.append([i0, i1, {what}])
    return [(a, b) for a, b, kinds in chains if len(kinds) == 2]


def fault_mask(n: int, faults, margin: int = 0) -> np.ndarray:
    """Boolean mask (n,) of the samples inside a fault span, widened by ``margin`` samples on both sides."""
    m = np.zeros(n, dtype=bool)
    for f in faults:
        m[max(0, f.i0 - margin):min(n, f.i1 + margin + 1)] = True
    return m


def repair_spikes(a: np.ndarray, faults, channel: str) -> np.ndarray:
    """``a`` with the single-sample spikes of ``channel`` replaced by the mean of their neighbours."""
    out = np.array(a, dtype=np.float64)
    for f in [p for f in faults for p in (f.parts or (f,))]:
        if f.kind == "spike" and f.channel == channel and 0 < f.i0 < out.size - 1:
            out[f.i0] = 0.5 * (out[f.i0 - 1] + out[f.i0 + 1])
    return out


def describe_faults(label: str, faults, n_excluded: int, n: int) -> str:
    """One message naming the faults and how many samples left the fit and the error measures."""
    shown = "; ".join(str(f) for f in faults[:8]) + (f"; and {len(faults) - 8} more" if len(faults) > 8 else "")
    return (f"record {label!r}: {len(faults)} fault(s) found and excluded from the fit and the error measures "
            f"({n_excluded} of {n} samples, {100 * n_excluded / n:.2f} %): {shown}. Pass faults='keep' to keep them "
            "or faults='raise' to refuse the record.")
