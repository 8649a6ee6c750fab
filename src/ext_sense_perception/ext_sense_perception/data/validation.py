"""Input rules for every import path: a clear error naming file, row and rule, or a counted drop.

By default the first bad row raises :class:`~ext_sense_perception.errors.PerceptionError`
naming the file, the 1-based row and the rule; a lenient :class:`InputPolicy` (``--lenient``)
drops the row (or the trial left empty) and counts it by rule.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from ext_sense_perception.errors import PerceptionError

NUSKIN_TAXELS = (1, 80)
NUSKIN_VALUE = (0, 1023)
"""The receiver's 10-bit value field."""
BIOTAC_ADC = (0, 4095)
"""BioTac samples are 12-bit ADC counts."""
EPOCH_S = (0.0, 4.0e9)
"""Host times are epoch seconds: after 1970 and before 2096."""

RULE_TIME = "time is not a finite number of epoch seconds in [0, 4e9]"
RULE_ORDER = "time goes backwards"
RULE_TAXEL = "taxel is not an integer in 1..80"
RULE_VALUE = "value is not an integer in 0..1023"
RULE_ADC = "sample is not an integer ADC count in 0..4095"
RULE_EMPTY = "trial has no valid event"
RULE_LABEL = "label is not a finite number"
RULE_WINDOW = "window holds NaN or inf"


@dataclass
class InputPolicy:
    """Strict (raise at the first bad row) or ``lenient`` (drop; ``dropped`` counts per rule)."""

    lenient: bool = False
    dropped: Counter[str] = field(default_factory=Counter)

    def keep(self, bad: np.ndarray, rule: str, where: str, shown: np.ndarray | None = None) -> None:
        """Raise a PerceptionError at the first ``bad`` row (strict), or count them (lenient).

        ``where`` names the file (and trial), ``shown`` the offending values for the message.
        """
        idx = np.flatnonzero(bad)
        if not idx.size:
            return
        if not self.lenient:
            got = f" (got {shown[idx[0]]!r})" if shown is not None else ""
            raise PerceptionError(
                f"{where}: row {int(idx[0]) + 1}: {rule}{got}; {idx.size} row(s) break this rule "
                "(--lenient drops and counts them instead)."
            )
        self.dropped[rule] += int(idx.size)

    def summary(self) -> str:
        """What was dropped, e.g. ``"dropped: 3 rows: taxel is not ...; 1 trial: ..."``."""
        if not self.dropped:
            return "dropped nothing"
        return "dropped " + "; ".join(f"{n} x {rule}" for rule, n in sorted(self.dropped.items()))


def _integer_in(x: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """Mask of values that are finite integers in ``[lo, hi]``."""
    with np.errstate(invalid="ignore"):
        return np.isfinite(x) & (x >= lo) & (x <= hi) & (np.floor(x) == x)


def check_event_rows(
    t_s: np.ndarray, taxel: np.ndarray, value: np.ndarray | None, where: str, policy: InputPolicy
) -> np.ndarray:
    """Mask of the rows of a NUSkin event file that satisfy every rule (strict: all, or an error).

    ``t_s`` are epoch seconds, ``value`` None when the format has none.
    """
    keep = np.ones(len(t_s), dtype=bool)
    with np.errstate(invalid="ignore"):
        bad = ~(np.isfinite(t_s) & (t_s >= EPOCH_S[0]) & (t_s <= EPOCH_S[1]))
    policy.keep(bad, RULE_TIME, where, t_s)
    keep &= ~bad
    bad = keep & ~_integer_in(taxel, *NUSKIN_TAXELS)
    policy.keep(bad, RULE_TAXEL, where, taxel)
    keep &= ~bad
    if value is not None:
        bad = keep & ~_integer_in(value, *NUSKIN_VALUE)
        policy.keep(bad, RULE_VALUE, where, value)
        keep &= ~bad
    # time order among the rows kept so far: a row earlier than the latest before it is bad
    idx = np.flatnonzero(keep)
    if idx.size > 1:
        kept_t = t_s[idx]
        backwards = kept_t < np.maximum.accumulate(kept_t)
        bad = np.zeros(len(t_s), dtype=bool)
        bad[idx[backwards]] = True
        policy.keep(bad, RULE_ORDER, where, t_s)
        keep &= ~bad
    return keep


def check_trial_not_empty(n_events: int, where: str, policy: InputPolicy) -> bool:
    """Whether a trial has events left (strict: an error when not; lenient: counted)."""
    if n_events:
        return True
    if not policy.lenient:
        raise PerceptionError(f"{where}: {RULE_EMPTY} (--lenient drops such trials).")
    policy.dropped[RULE_EMPTY] += 1
    return False
