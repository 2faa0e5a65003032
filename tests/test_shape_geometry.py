"""The shape parametrisation of geometry fits (``refine.model.parametrize.ShapeGeometry``): ellipses
moved by their symmetric shape matrix, rectangles by centre, half sides and angle."""

import numpy as np


def test_shape_geometry_turns_an_ellipse_onto_any_other():
    """With ``rotate`` the morph takes a shape's curve exactly onto an ellipse of other centre, axes
    and orientation, also from a circle (where an angle alone is undefined: the symmetric shape
    matrix has a full-rank Jacobian there); without it, the old axis-aligned morph is kept."""
    import jax
    import jax.numpy as jnp

    import jaxfem as jf
    from jaxfem.shapes import curve_nodes
    from refine.model.parametrize import ShapeGeometry

    rng = np.random.default_rng(7)
    for start in (jf.Ellipse(50.0, 30.0, *rng.uniform(6, 9, 2), rng.uniform(0, np.pi)), jf.Ellipse(50.0, 30.0, 7.0, 7.0)):
        mesh = jf.plate(0, 0, 100, 60, 3.0, holes=[start])
        mo = jf.morph(mesh, [start])
        geo = ShapeGeometry(mo, np.asarray(mo.params0), scale=2.0, rotate=True)
        target = jf.Ellipse(*(np.asarray(start.params[:2]) + rng.uniform(-1, 1, 2)),
                            *(rng.uniform(0.8, 1.2, 2) * start.params[2:4]), start.params[4] + rng.uniform(-0.6, 0.6))

        def sym(p):
            c, s = np.cos(p[4]), np.sin(p[4])
            R = np.array([[c, -s], [s, c]])
            return R @ np.diag(p[2:4]) @ R.T

        dM = (sym(target.params) - sym(start.params)) / geo.scale
        z = np.r_[(target.params[:2] - start.params[:2]) / geo.scale, dM[0, 0], dM[1, 1], dM[0, 1]]
        X = np.asarray(geo.apply({}, z)["X"])
        on = curve_nodes(mesh, start)
        assert np.abs(np.linalg.norm(X[on] - target.to_curve(X[on]), axis=1)).max() < 1e-9
        p = geo.shape_params(z)[0]
        same = np.allclose(p[2:4], target.params[2:4]) and abs(np.sin(p[4] - target.params[4])) < 1e-9
        swapped = np.allclose(p[2:4], target.params[3:1:-1]) and abs(np.cos(p[4] - target.params[4])) < 1e-9
        assert same or swapped, (p, target.params)
        assert abs(p[4] - start.params[4]) <= np.pi / 2 + 1e-9  # stays within a quarter turn of the start
        J = np.asarray(jax.jacfwd(lambda zz: geo.apply({}, zz)["X"][on].reshape(-1))(jnp.zeros(5)))
        assert np.linalg.matrix_rank(J) == 5

    fixed = ShapeGeometry(mo, np.asarray(mo.params0), scale=2.0)
    z4 = rng.uniform(-0.5, 0.5, 4)
    assert fixed.size == 4 and geo.size == 5
    np.testing.assert_allclose(fixed.apply({}, z4)["X"], mo(jnp.asarray(fixed.shape_params(z4))), atol=1e-12)


def test_shape_geometry_moves_a_rectangle_as_a_rectangle():
    """A ``"rectangle"`` shape beside an ellipse in one morph: its z are centre, half sides and
    angle, and its corners land exactly on the rectangle asked for (a symmetric map, as for the
    ellipse, would shear it into a parallelogram); the ellipse still moves by its shape matrix;
    the Jacobian of the rectangle's curve nodes has full rank 5; a side below ``min_axis`` is
    infeasible."""
    import jax
    import jax.numpy as jnp

    import jaxfem as jf
    from jaxfem.shapes import curve_nodes
    from refine.model.parametrize import ShapeGeometry

    rng = np.random.default_rng(11)
    rect = jf.Rect(20.0, 20.0, 20.0 + rng.uniform(10, 16), 20.0 + rng.uniform(8, 12), rng.uniform(-0.3, 0.3))
    ell = jf.Ellipse(75.0, 30.0, 6.0, 4.0, 0.4)
    mesh = jf.plate(0, 0, 100, 60, 3.0, inclusions=[rect, ell])
    mo = jf.morph(mesh, [rect, ell])
    geo = ShapeGeometry(mo, np.asarray(mo.params0), scale=2.0, rotate=True, kinds=("rectangle", "ellipse"),
                        min_axis=1.0)
    p0 = rect.params
    target = p0 + np.r_[rng.uniform(-1, 1, 2), rng.uniform(-1.5, 1.5, 2), rng.uniform(-0.25, 0.25)]
    z = np.zeros(10)
    z[:4] = (target[:4] - p0[:4]) / geo.scale
    z[4] = (target[4] - p0[4]) * np.sqrt(p0[2] * p0[3]) / geo.scale
    X = np.asarray(geo.apply({}, z)["X"])
    on = curve_nodes(mesh, rect)
    moved = jf.Rect(target[0] - target[2], target[1] - target[3], target[0] + target[2], target[1] + target[3], target[4])
    assert np.linalg.norm(X[on] - moved.to_curve(X[on]), axis=1).max() < 1e-9
    from refine.diagnosis.localize import rectangle_polygon

    for ref, new in zip(rectangle_polygon(*p0), rectangle_polygon(*target)):  # each corner onto its corner
        k = np.argmin(np.linalg.norm(mo.nodes0 - ref, axis=1))
        np.testing.assert_allclose(X[k], new, atol=1e-3)  # the polygon is rounded to 4 decimals
    np.testing.assert_allclose(geo.shape_params(z)[0], target, atol=1e-12)
    np.testing.assert_allclose(X[curve_nodes(mesh, ell)], mo.nodes0[curve_nodes(mesh, ell)], atol=1e-12)  # z = 0 there
    assert [type(s).__name__ for s in geo.shapes(z)] == ["Rect", "Ellipse"]
    J = np.asarray(jax.jacfwd(lambda zz: geo.apply({}, zz)["X"][on].reshape(-1))(jnp.zeros(10)))
    assert np.linalg.matrix_rank(J[:, :5]) == 5
    thin = np.zeros(10)
    thin[3] = (0.9 - p0[3]) / geo.scale
    assert "semi-axis" in geo.infeasibility(thin)
    assert geo.infeasibility(z) is None
