"""The paper's cup holder (Sec. 4): its geometry generator (:mod:`examples.cup_holder.geometry`)."""

from examples.cup_holder.geometry import CupHolder, cup_bottom, cup_holder

__all__ = ["CupHolder", "cup_bottom", "cup_holder"]
