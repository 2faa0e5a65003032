"""jaxfem: a differentiable total-Lagrangian hyperelastic finite-element solver in JAX.

Build a :class:`Mesh`, state a :class:`Problem` (material law, kinematics, prescribed dofs),
make a :class:`Solver` once, then solve or differentiate for any parameters::

    import jaxfem as jf
    mesh = jf.rectangle(0, 0, 100, 60, 50, 30)
    fixed = jf.dofs(mesh, mesh.side("left")), jf.dofs(mesh, mesh.side("right"))
    problem = jf.Problem(mesh, "neo-hookean", "plane-stress", fixed=np.concatenate(fixed))
    solver = jf.Solver(problem)
    theta = problem.params(E=83.76, nu=0.3, u_D=problem.prescribe(lambda X: 0.2 * X * [1, 0]))
    u = solver.solve(theta).u                 # raises SolverError with the failing load step
    g = jax.grad(lambda th: solver.displacement(th).sum())(theta)   # one adjoint solve

Everything is float64.
"""

from . import _config  # noqa: F401
from .batch import batch_displacement, stack_params
from .derivatives import taylor_test
from .elements import ELEMENTS, Element, get_element
from .geometry import check_geometry, with_geometry
from .exceptions import InvertedElementError, JaxfemError, MeshError, ProblemError, SolverError
from .io import read_mesh, read_pvd, to_meshio, write_points_vtu, write_pvd, write_vtu
from .materials import LAWS, Material, get_material, lame
from .mesh import Mesh, box, check_orientation, fix_orientation, rectangle, to_quadratic
from .newton import NewtonOptions
from .probe import BoundaryProjection, Probe, boundary_interpolation, boundary_loop, locate, project_to_boundary
from .problem import Problem, dofs
from .postprocess import (cauchy_stress, deformation_gradient, equivalent_strain, first_piola_stress,
                      green_lagrange_strain, principal_strains, second_piola_stress, strain_energy,
                      von_mises_stress)
from .mesher import domain, plate
from .wall import ExtrudedWall, disc_wall, rimmed_wall
from .surface import surface_interpolation
from .shapes import Ellipse, Polygon, Rect, curve_nodes, morph
from .solver import Solution, Solver
from .cache import cache_info, clear_cache, compilation_cache, compile_counts, compiles_since
from .series import equilibrium_series
from . import plot

__all__ = [
    "ELEMENTS", "Element", "get_element", "InvertedElementError", "JaxfemError", "MeshError",
    "ProblemError", "SolverError", "read_mesh", "read_pvd", "to_meshio", "write_points_vtu", "write_pvd",
    "write_vtu", "LAWS", "Material",
    "get_material", "lame", "Mesh", "box", "check_orientation", "fix_orientation", "rectangle",
    "to_quadratic", "NewtonOptions", "Probe", "boundary_interpolation", "boundary_loop", "locate",
    "BoundaryProjection", "project_to_boundary",
    "Problem", "dofs", "cauchy_stress", "deformation_gradient", "equivalent_strain",
    "first_piola_stress", "green_lagrange_strain", "principal_strains", "second_piola_stress",
    "strain_energy", "von_mises_stress", "Ellipse", "Polygon", "Rect", "curve_nodes", "morph", "plate", "domain",
    "Solution", "Solver", "taylor_test", "batch_displacement", "stack_params", "check_geometry",
    "with_geometry", "equilibrium_series", "ExtrudedWall", "disc_wall", "rimmed_wall", "surface_interpolation",
    "compilation_cache", "cache_info", "clear_cache", "compile_counts", "compiles_since",
]
