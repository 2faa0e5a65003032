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
            at the same size are too stiff in a strongly strained region and bias its ratio).
        hole_below: a softer region fitted at less than this ratio is also fitted as a hole from
            its fitted outline (a hole started from the candidate's rough outline can settle in
            a worse place than the very soft region does, and then loses the comparison).
        hole_refit_below: a chosen softer region whose refit on every guide point falls below
            this ratio (it carries almost no load) is compared with a hole at its outline once
            more (:func:`~refine.diagnosis.pipeline._hole_if_as_likely`); lower than
            ``hole_below`` because the hole's fit and remesh cost true soft regions minutes.
        seed: seeds the holdout split.
        try_rectangles: when the first region, fitted as an ellipse, is the best hypothesis so
            far, also fit it as a rectangle (from the ellipse, turned 0 and pi/4, beside the
            ellipse remeshed at its fit); the best score is kept. False (default): never; True:
            always; None: only where the tracked points resolve a rectangle's corners, i.e. the
            fitted ellipse's smaller semi-axis is at least ``rectangle_spacings`` grid spacings.
            Fitted as ellipses, rectangles come out larger and too soft; on coarse grids
            rectangles out-score true ellipses too. Off by default: it costs tens of seconds per
            diagnosis and the gate is not yet validated over the benchmark's cells.
        rectangle_spacings: the gate of ``try_rectangles=None``, in grid spacings (1.5: a side
            spans at least three grid intervals).
        workers: hypotheses (and the set-up's independent models) fitted side by side in this
            many threads; XLA compiles and solves outside Python's lock, and compilation is most
            of a diagnosis.
        max_cells: the models' element size is half the point spacing, but at most this many
            linear triangles over the domain (:func:`refine.diagnosis.scale.mesh_size`): the
            cost of a solve follows the domain, not the number of tracked points.
        search_frames: the null test, the field and every hypothesis use this many frames, those
            of most motion (:func:`refine.diagnosis.scale.search_frames`); the chosen model is
            refitted on every frame. 0: all frames.
        strain_candidates: at most this many candidate regions also from the measured strain
            map (:func:`refine.diagnosis.candidates.strain_regions`), beside the field's and the
            gaps in the points.
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
    max_cells: int = 3000
    search_frames: int = 2
    strain_candidates: int = 1
