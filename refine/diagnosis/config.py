"""Settings of a diagnosis."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class DiagnoseConfig:
    """Settings of a diagnosis (data, not a dozen keyword arguments).

    Attributes:
        alpha: significance of the null test (a misfit this unlikely under the initial model
            means something is wrong).
        holdout_fraction: share of guide points held out to choose between hypotheses.
        bic_margin: how much lower than the initial model's BIC a hypothesis must score.
        field_weight: smoothing weight of the localisation field (x number of residuals / cells).
        max_regions: largest number of regions tried.
        try_laws: also try other material laws.
        refit_element: element of the chosen model's final meshes (``"tri6"``: linear triangles
            at the same size are too stiff in a strongly strained region; on one soft region at
            2.5 mm elements, fitted at its true shape without noise, the ratio came out 9 % low
            with tri3 and 0.4 % low with tri6).
        hole_below: a softer region fitted at less than this ratio is also fitted as a hole from
            its fitted outline (a hole started from the candidate's rough outline can settle in
            a worse place than the very soft region does, and then loses the comparison). On a
            10 mm-grid hole (seed 10300) the first hole fit reached chi2 279 against the soft
            region's 271 (ratio 0.06), the second 227: named a hole now. A true soft region of
            ratio 0.19 (seed 10200, fitted 0.18) gave second hole fits of chi2 1413 against 247.
            At 0.3: a 5 mm-grid hole with noise 0.05 mm (seed 5300) is fitted as a soft region
            of ratio 0.21 first.
        hole_refit_below: a chosen softer region whose refit on every guide point falls below
            this ratio (it carries almost no load) is compared with a hole at its outline once
            more (:func:`_hole_if_as_likely`). At ``hole_below`` it cost true soft regions on
            10 mm grids up to 2 minutes more (their outline holds no tracked point, so the hole
            is fitted and remeshed); the two holes it is for were refitted to ratio 0.00.
        seed: seeds the holdout split.
        try_rectangles: when the first region, fitted as an ellipse, is the best hypothesis so
            far, also fit it as a rectangle (from the ellipse, turned 0 and pi/4, beside the
            ellipse remeshed at its fit); the best score is kept. False (default): never; True:
            always; None: only where the tracked points resolve a rectangle's corners, i.e. the
            fitted ellipse's smaller semi-axis is at least ``rectangle_spacings`` grid spacings.
            Fitted as ellipses, the paper's rectangles come out larger and 12-30 % too soft;
            on 5 mm grids a rectangle fit puts 5/5 within 10 % (3/5 without) at noise 0.02 mm,
            areas within 2.3 % (were +10-20 %). On 10 mm grids (two grid intervals per side)
            rectangles out-score true ellipses too (a soft ellipse's ratio 28 % off as a
            rectangle, 6 % as an ellipse): the gate (None) keeps them off there. It costs
            15-30 s per diagnosis where it runs, more for two regions (146-184 s on one 5 mm
            two-region bundle under load, against the 2-minute target), and the gate is not yet
            validated over the benchmark's cells: hence off by default.
        rectangle_spacings: the gate of ``try_rectangles=None``, in grid spacings (1.5: a side
            spans at least three grid intervals).
        workers: hypotheses (and the set-up's independent models) fitted side by side in this
            many threads; XLA compiles and solves outside Python's lock, so on 2 cores two
            compilations or fits take little longer than one (compilation is most of a
            diagnosis: 55 of 71 s on one 5 mm stiffer-region bundle).
    """

    alpha: float = 1e-3
    holdout_fraction: float = 0.25
    bic_margin: float = 10.0
    field_weight: float = 2.0
    max_regions: int = 2
    try_laws: bool = True
    refit_element: str = "tri6"
    hole_below: float = 0.3
    hole_refit_below: float = 0.05
    seed: int = 0
    workers: int = 2
    try_rectangles: bool | None = False
    rectangle_spacings: float = 1.5
