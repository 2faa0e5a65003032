"""The paper's skin with a stiffer scar (Secs. 3.2 and 5.1): :mod:`examples.skin.synthetic`."""

from examples.skin.synthetic import SKIN, SkinSetting, random_scar, skin_bundle

__all__ = ["SKIN", "SkinSetting", "random_scar", "skin_bundle"]
