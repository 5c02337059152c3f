"""Two evaluation runs compared sample by sample: an exact McNemar test on the same keys.

A change to how keyposes are decoded or planned (``--hand-half-turn``, a checkpoint's
``decode_sigma_px``) is judged on the samples both runs executed: same key, hence the same
object, reset seed and sample seed. Samples that succeed in both runs or fail in both say
nothing about the change; only the discordant ones do, so their two counts carry the test.
Comparing the two pooled SSRs instead (two Wilson intervals, or Fisher's test) treats the runs as
independent and spends the pairing: with 1536 samples per split a 2-point change is inside
either run's interval yet can be clear in the discordant counts.

McNemar's exact test is the two-sided binomial test of ``only_a`` out of ``only_a + only_b``
discordant samples at 1/2 (McNemar 1947; the exact form is recommended over the chi-squared one
for the small discordant counts of a category cell, Fagerland et al. 2013). The adoption rules
in docs/evaluation.md are written against its p-value.

Two methods of one run are paired the same way, by scene: :func:`scene_pairs` keeps the scenes
(object and reset seed) both ran, per seed's run, and pools each object's over the seeds for
``stats.paired_bootstrap`` (the protocol's "beats Data Collection" rule).
"""
from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass
from typing import Mapping, Sequence

from actaim2.eval.tables import AVG
from actaim2.keypose import PHASE_NAMES
from actaim2.metrics.mode_ssr import GroupSample, halving_rule
from actaim2.metrics.stats import PairedCounts, Rate, paired_bootstrap

# A record's fields that must agree for two records of one key to be the same sample.
SAME_SAMPLE = ("object", "split", "reset_seed", "sample_seed", "requested_cluster")


class UnpairedError(ValueError):
    """The two runs share no sample, or a key names different samples in them (named in the message)."""


def mcnemar_exact(only_a: int, only_b: int) -> float:
    """Two-sided exact McNemar p-value of the discordant counts; 1 when there is none."""
    from scipy.stats import binomtest

    if only_a < 0 or only_b < 0:
        raise ValueError(f"discordant counts must be >= 0, got {only_a} and {only_b}")
    if only_a + only_b == 0:
        return 1.0
    return float(binomtest(only_a, only_a + only_b, 0.5).pvalue)


@dataclass(frozen=True)
class PairedCell:
    """The paired samples of one (method, split, category or AVG): the 2 x 2 table and phase counts."""

    both: int = 0
    only_a: int = 0
    only_b: int = 0
    neither: int = 0
    ran_a: int = 0  # samples that ran all four phases in run A
    ran_b: int = 0

    @property
    def samples(self) -> int:
        return self.both + self.only_a + self.only_b + self.neither

    @property
    def rate_a(self) -> Rate:
        return Rate(self.both + self.only_a, self.samples)

    @property
    def rate_b(self) -> Rate:
        return Rate(self.both + self.only_b, self.samples)

    @property
    def p_value(self) -> float:
        return mcnemar_exact(self.only_a, self.only_b)

    def __add__(self, other: "PairedCell") -> "PairedCell":
        return PairedCell(self.both + other.both, self.only_a + other.only_a, self.only_b + other.only_b,
                          self.neither + other.neither, self.ran_a + other.ran_a, self.ran_b + other.ran_b)


def pair_records(a: Mapping[str, dict], b: Mapping[str, dict]) -> list[tuple[dict, dict]]:
    """The (record in A, record in B) of every key both runs finished, in key order.

    Raises :class:`UnpairedError` if no key is shared, or if a shared key names another sample
    in the two runs (another evaluation set or seed scheme: pairing them would compare noise)."""
    keys = sorted(set(a) & set(b))
    if not keys:
        raise UnpairedError("the two runs share no sample key: were they made on the same splits and methods?")
    for key in keys:
        different = [f for f in SAME_SAMPLE if a[key].get(f) != b[key].get(f)]
        if different:
            raise UnpairedError(f"key {key} is another sample in the two runs ({', '.join(different)} differ): "
                                f"their evaluation sets differ, so their samples cannot be paired")
    return [(a[k], b[k]) for k in keys]


def paired_cells(pairs: Sequence[tuple[dict, dict]]) -> dict[tuple[str, str, str], PairedCell]:
    """(method, split, category or AVG) -> the paired cell over those samples."""
    phases = len(PHASE_NAMES)
    cells: dict[tuple[str, str, str], PairedCell] = defaultdict(PairedCell)
    for ra, rb in pairs:
        sa, sb = bool(ra["success"]), bool(rb["success"])
        one = PairedCell(both=int(sa and sb), only_a=int(sa and not sb), only_b=int(sb and not sa),
                         neither=int(not (sa or sb)), ran_a=int(ra["phases_executed"] == phases),
                         ran_b=int(rb["phases_executed"] == phases))
        for category in (ra["category"], AVG):
            cells[ra["method"], ra["split"], category] += one
    return dict(cells)


def paired_table(pairs: Sequence[tuple[dict, dict]], titles: Mapping[str, str] | None = None,
                 split_titles: Mapping[str, str] | None = None) -> list[str]:
    """Markdown table, one line per (method, split, category) with each split's AVG first."""
    titles, split_titles = titles or {}, split_titles or {}
    cells = paired_cells(pairs)
    order = sorted(cells, key=lambda k: (k[0], k[1], k[2] != AVG, k[2]))
    lines = ["| method | split | category | paired samples | SSR % A [95 %] | SSR % B [95 %] | only A | only B | "
             "McNemar exact p | ran all four phases, A / B |", "|---" * 10 + "|"]
    for method, split, category in order:
        c = cells[method, split, category]
        name = f"**{category}**" if category == AVG else category
        lines.append(f"| {titles.get(method, method)} | {split_titles.get(split, split)} | {name} | {c.samples} | "
                     f"{c.rate_a.cell()} | {c.rate_b.cell()} | {c.only_a} | {c.only_b} | {c.p_value:.3g} | "
                     f"{100 * c.ran_a / c.samples:.1f} % / {100 * c.ran_b / c.samples:.1f} % |")
    return lines


def scene_pairs(runs: Sequence[Sequence[dict]], method_a: str,
                method_b: str) -> list[PairedCounts]:
    """Per object, the scenes (same object and reset seed, within one seed's run) that both
    methods ran, pooled over ``runs`` (one record list per seed), by object key; objects with
    none left out."""
    totals: dict[str, list] = {}
    for records in runs:
        by_scene: dict[str, dict[tuple[str, int], dict]] = {method_a: {}, method_b: {}}
        for r in records:
            if r["method"] in by_scene:
                by_scene[r["method"]][r["object"], r["reset_seed"]] = r
        for scene in sorted(set(by_scene[method_a]) & set(by_scene[method_b])):
            ra, rb = by_scene[method_a][scene], by_scene[method_b][scene]
            entry = totals.setdefault(scene[0], [ra["category"], 0, 0, 0])
            entry[1] += 1
            entry[2] += int(bool(ra["success"]))
            entry[3] += int(bool(rb["success"]))
    return [PairedCounts(category, scenes, sa, sb)
            for _, (category, scenes, sa, sb) in sorted(totals.items())]


def component_groups(records: Sequence[dict], method: str) -> list[dict]:
    """``records`` with ``method``'s samples regrouped by the GMM cluster each slot drew from
    (``gmm_clusters`` K recorded on an object's samples: slot s draws from cluster s mod K,
    repetition s // K) instead of by pseudo-cluster; other records are returned as they are. An
    object with no recorded K (no sampler, every sample refused) is one group."""
    clusters = {r["object"]: r["gmm_clusters"] for r in records if r["method"] == method and "gmm_clusters" in r}
    if not clusters:
        return list(records)
    out = []
    for r in records:
        if r["method"] == method:
            k = clusters.get(r["object"], 1)
            r = {**r, "group": r["slot"] % k, "repetition": r["slot"] // k}
        out.append(r)
    return out


def _group_samples(runs: Sequence[Sequence[dict]], methods: Sequence[str]) -> dict:
    """method -> object -> per run, its samples as Mode SSR reads them (group, repetition, mode)."""
    samples: dict[str, dict[str, list[list[GroupSample]]]] = {m: {} for m in methods}
    for records in runs:
        per_run: dict[tuple[str, str], list[GroupSample]] = {}
        for r in records:
            if r["method"] in samples and r.get("group", -1) >= 0:
                mode = tuple(r["mode"]) if r["mode"] else None
                per_run.setdefault((r["method"], r["object"]), []).append(
                    GroupSample(r["group"], r["repetition"], mode))
        for (name, obj), group_samples in per_run.items():
            samples[name].setdefault(obj, []).append(group_samples)
    return samples


def comparison(runs: Sequence[Sequence[dict]], method: str, baseline: str, halvings: int,
               rounds: int, seed: int = 0) -> list[str]:
    """Markdown: ``method`` against ``baseline`` by the protocol's two rules, per split, over the
    records of each seed's run (seeds pooled), with each seed's SSRs listed."""
    splits = sorted({r["split"] for records in runs for r in records if r["method"] == method}
                    & {r["split"] for records in runs for r in records if r["method"] == baseline})
    if not splits:
        raise ValueError(f"no split has records of both {method} and {baseline}")
    lines = [f"# {method} against {baseline}: the protocol's rules, {len(runs)} seed(s) pooled",
             ""]
    components = [component_groups(records, baseline) for records in runs]
    by_component = any(r is not c for records, grouped in zip(runs, components) for r, c in zip(records, grouped))
    for split in splits:
        mine = [[r for r in records if r["split"] == split] for records in runs]
        ssr = paired_bootstrap(scene_pairs(mine, method, baseline), rounds, seed)
        categories = {r["object"]: r["category"] for records in mine for r in records}
        samples = _group_samples(mine, (method, baseline))
        second = halving_rule(samples[method], samples[baseline], categories, 2, halvings, rounds,
                              seed)
        rows = [("2nd-mode SSR", second)]
        if by_component:  # the baseline's modes by its own GMM components too
            own = _group_samples([[r for r in records if r["split"] == split] for records in components],
                                 (baseline,))
            rows.append((f"2nd-mode SSR, {baseline} by its GMM components",
                         halving_rule(samples[method], own[baseline], categories, 2, halvings, rounds, seed)))
        lines += [f"## {split}", "",
                  "| rule | pooled [95 %] | category macro-average [95 %] | holds |",
                  "|---|---|---|---|",
                  f"| SSR, paired scenes | {ssr.pooled.cell()} | {ssr.macro.cell()} | "
                  f"{'yes' if ssr.above_zero else 'no'} |",
                  *(f"| {name}, {halvings} halvings (positive in {100 * rule.positive_share:.0f} %) "
                    f"| {rule.difference.pooled.cell()} | {rule.difference.macro.cell()} "
                    f"| {'yes' if rule.holds else 'no'} |" for name, rule in rows), "",
                  "| seed | " + f"{method} SSR % | {baseline} SSR % |", "|---|---|---|"]
        for k, records in enumerate(mine):
            rates = [Rate(sum(bool(r["success"]) for r in records if r["method"] == m),
                          sum(r["method"] == m for r in records)) for m in (method, baseline)]
            lines.append(f"| {k} | {rates[0].cell()} | {rates[1].cell()} |")
        lines.append("")
    return lines
