"""Plain-language warnings about an evaluation: too few states matched to truth, sigmas that do not fit."""

from __future__ import annotations

from .trajectory import MATCH_TOLERANCE

# Truth normally covers the whole run at the state rate or faster (motion capture); fewer than half
# of the states matched means another clock, a slower truth or truth of part of the run, and the ATE
# then describes only the matched part.
MIN_MATCHED_SHARE = 0.5


def _shares(percent: dict, axes: list[str]) -> str:
    return ", ".join(f"{a} {percent[a]['1sigma']:.0f}/{percent[a]['2sigma']:.0f}/{percent[a]['3sigma']:.0f} %"
                     for a in axes)


def evaluation_notes(evaluation: dict) -> list[str]:
    """One note per robot whose truth matched under half of its states, and per robot and verdict
    of `consistency_check` (overconfident / underconfident sigmas, with the axes and their shares)."""
    notes = []
    for robot, ev in evaluation.get("trajectories", {}).items():
        n, m = ev["matched_poses"], ev["states"]
        if n == 0:
            notes.append(f"truth of {robot}: no truth pose within {MATCH_TOLERANCE} s of any of its {m} states; "
                         "no ATE (check that truth and data share a clock)")
        elif n < MIN_MATCHED_SHARE * m:
            notes.append(f"truth of {robot}: only {n} of {m} states have a truth pose within {MATCH_TOLERANCE} s; "
                         "the ATE and consistency cover those alone (check that truth and data share a clock)")
        check = ev.get("consistency_check")
        if not check:
            continue
        for verdict, meaning in (("overconfident", "the errors against truth are larger than the sigmas say"),
                                 ("underconfident", "the errors against truth are smaller than the sigmas say")):
            axes = check[verdict]
            if axes:
                notes.append(f"sigmas of {robot} {', '.join(axes)} are {verdict} (inside 1/2/3 sigma: "
                             f"{_shares(ev['consistency_percent'], axes)}; ideal 68/95/99.7 %): {meaning}; "
                             "check the noise sigmas of the factors")
    return notes
