"""The ``nonrigid`` command line: one module per command, each with a public function.

    simulate(bundle, out, h=None, quiet=False) -> dict           nonrigid simulate
    diagnose(bundle, out, config=None, quiet=False) -> Diagnosis nonrigid diagnose
    track(images, out, pattern=..., scale=..., roi=..., ...) -> Bundle   nonrigid track
    import_export(sources, out, format="dice"|"csv", scale=...) -> Bundle   nonrigid import
    demo(out, seed=None) -> Diagnosis                             nonrigid demo
    follow(bundle, out, grips=None, h=5.0, ...) -> FollowResult  nonrigid follow

The functions shadow their modules' names here; reach a module with
``from refine.cli.track import add_parser`` or ``importlib.import_module("refine.cli.track")``.
Importing this package imports neither JAX nor jaxfem (the functions import them when called).
"""

from refine.cli.main import main
from refine.cli.demo import demo
from refine.cli.diagnose import diagnose
from refine.cli.follow import follow
from refine.cli.import_export import import_export
from refine.cli.simulate import simulate
from refine.cli.track import track

__all__ = ["demo", "diagnose", "follow", "import_export", "main", "simulate", "track"]
