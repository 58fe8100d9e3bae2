"""Paths and head references: exact derivatives, arc length, continuity, files, distances."""

from __future__ import annotations

import math
import os
from pathlib import Path as FilePath

import numpy as np
import pytest

from snake_pin.control import head_first_reference
from snake_pin.exceptions import ParameterError
from snake_pin.paths import (
    Arc,
    Circle,
    LaneChange,
    Line,
    Path,
    PathFileError,
    PathReference,
    Sinusoid,
    Timing,
    Waypoints,
    along_track,
    cross_track_error,
    load_path,
    make_path,
)

from .conftest import raised_without_blocking

#: A loop of waypoints whose heading passes through +-pi (it heads back along -x).
LOOP = [(0.0, 0.0), (1.0, 0.2), (2.0, -0.5), (2.5, 1.0), (1.0, 1.5), (-1.0, 0.5)]

PATHS: dict[str, Path] = {
    "line": Line(start=(1.0, 2.0), direction=2.5),
    "circle": Circle(radius=0.6),
    "circle_cw": Circle(radius=1.0, clockwise=True, centre=(1.0, 1.0), start_angle=0.3),
    "arc": Arc(radius=0.8, angle=2.0),
    "lane_change": LaneChange(offset=-0.4, length_x=1.5, start=0.3, direction=0.7),
    "sinusoid": Sinusoid(amplitude=0.3, wavelength=1.5, origin=(1.0, 0.0), direction=-0.4),
    "waypoints": Waypoints(points=LOOP),
}


@pytest.fixture(params=list(PATHS), ids=list(PATHS))
def path(request: pytest.FixtureRequest) -> Path:
    return PATHS[request.param]


def _span(path: Path) -> np.ndarray:
    """Arc lengths over the defined part and beyond both ends (at most 8 m)."""
    return np.linspace(-0.5, min(path.length, 8.0) + 0.5, 4001)


def test_derivatives_match_central_differences(path: Path, rng: np.random.Generator) -> None:
    """w_r' and w_r'' equal central differences of w_r and w_r' (ramp included)."""
    ref = PathReference(path, Timing(speed=0.13, ramp=2.0))
    h = 1e-5
    for t in np.r_[rng.uniform(-1.0, 70.0, 25), 0.7, 1.9]:
        _, dw, ddw = ref(t)
        w_p, dw_p, _ = ref(t + h)
        w_m, dw_m, _ = ref(t - h)
        np.testing.assert_allclose((w_p - w_m) / (2 * h), dw, atol=1e-8)
        np.testing.assert_allclose((dw_p - dw_m) / (2 * h), ddw, atol=1e-7)


def test_scalar_and_vectorised_references_agree(path: Path, rng: np.random.Generator) -> None:
    """The per-step float path and PathReference.at give the same w_r, w_r', w_r''."""
    ref = PathReference(path, Timing(speed=0.13, ramp=2.0, start=-0.2))
    ts = np.r_[rng.uniform(-1.0, 70.0, 50), 0.0, 2.0]
    batch = ref.at(ts)
    for k, t in enumerate(ts):
        for single, many in zip(ref(t), batch, strict=True):
            np.testing.assert_allclose(single, many[k], rtol=1e-12, atol=1e-12)


def test_arc_length_parametrisation(path: Path) -> None:
    """|dp/ds| = 1, d gamma/ds = kappa and d kappa/ds = dkappa (central differences)."""
    s, h = _span(path), 1e-5
    g, g_p, g_m = path.geometry(s), path.geometry(s + h), path.geometry(s - h)
    dp = (g_p.p - g_m.p) / (2 * h)
    np.testing.assert_allclose(np.linalg.norm(dp, axis=1), 1.0, atol=1e-7)
    np.testing.assert_allclose(dp, g.tangent, atol=1e-7)
    smooth = (np.abs(g_p.kappa - g_m.kappa) < 1e-3)  # away from an arc's ends
    np.testing.assert_allclose(((g_p.gamma - g_m.gamma) / (2 * h))[smooth], g.kappa[smooth],
                               atol=1e-6)
    if path.name not in ("waypoints", "arc"):  # kappa' jumps at spline knots, arc ends
        np.testing.assert_allclose((g_p.kappa - g_m.kappa) / (2 * h), g.dkappa, atol=1e-5)


def test_heading_is_continuous(path: Path) -> None:
    """No jump in theta_1 between close samples, also where the tangent crosses +-pi."""
    ref = PathReference(path, Timing(speed=0.1))
    ts = np.linspace(-5.0, 80.0, 85001)  # 1 mm of path between samples
    heading = ref.at(ts)[0][:, 2]
    assert np.max(np.abs(np.diff(heading))) < 5e-3
    if path.name in ("circle", "circle_cw", "waypoints"):
        # these sweep past theta_1 = +-pi (mod 2 pi) without a 2 pi jump
        crossings = np.floor((heading - np.pi) / (2 * np.pi))
        assert crossings.min() != crossings.max()


def test_head_first_convention() -> None:
    """theta_1 = tangent angle + pi; a line along +x at 0.1 m/s is the paper's reference."""
    paper, line = head_first_reference(0.1), PathReference(Line(), Timing(0.1))
    for t in (0.0, 3.7, 59.0):
        for a, b in zip(paper(t), line(t), strict=True):
            np.testing.assert_allclose(a, b, atol=1e-15)
    w = PathReference(Line(direction=0.5))(1.0)[0]
    assert w[2] == pytest.approx(0.5 + np.pi)


@pytest.mark.parametrize("name", ["lane_change", "waypoints"])
def test_second_derivative_continuous_at_joins(name: str) -> None:
    """p'' = kappa n has no jump where pieces meet (lane change also kappa', C3)."""
    path = PATHS[name]
    if name == "lane_change":
        joins = np.array([path.start, path.start + path.s_length])
    else:
        joins = np.r_[path.knots_s, 0.0, path.length]
    eps = 1e-7
    left, right = path.geometry(joins - eps), path.geometry(joins + eps)
    np.testing.assert_allclose(left.kappa, right.kappa, atol=1e-5)
    np.testing.assert_allclose(left.tangent, right.tangent, atol=1e-6)
    assert np.any(np.abs(path.geometry(np.linspace(0, path.length if math.isfinite(
        path.length) else 3.0, 50)).kappa) > 0.1)  # the pieces do bend
    if name == "lane_change":
        np.testing.assert_allclose(left.dkappa, right.dkappa, atol=1e-4)


def test_spline_passes_through_its_waypoints() -> None:
    """p(s_k) is waypoint k, and the ends have zero curvature (natural spline)."""
    path = PATHS["waypoints"]
    np.testing.assert_allclose(path.point(path.knots_s), LOOP, atol=1e-12)
    assert np.abs(path.geometry(np.array([0.0, path.length])).kappa).max() < 1e-9


def test_circle_geometry() -> None:
    """Default circle: through the origin heading +x, centre (0, R), kappa = 1/R, laps on."""
    circle = Circle(radius=1.2)
    assert circle.centre == pytest.approx((0.0, 1.2))
    g = circle.geometry(np.array([0.0, circle.length / 4, 2.5 * circle.length]))
    np.testing.assert_allclose(g.p, [[0, 0], [1.2, 1.2], [0, 2.4]], atol=1e-12)
    np.testing.assert_allclose(g.gamma, [0.0, np.pi / 2, 5 * np.pi])
    np.testing.assert_allclose(g.kappa, 1 / 1.2)
    cw = Circle(radius=2.0, clockwise=True)
    assert cw.centre == pytest.approx((0.0, -2.0))
    assert cw.geometry(1.0).kappa == pytest.approx(-0.5)


def test_cross_track_error_of_offset_points(path: Path, rng: np.random.Generator) -> None:
    """Points moved d along the left normal are at signed distance d, closest at s."""
    s = rng.uniform(0.0, min(path.length, 6.0), 200)
    g = path.geometry(s)
    d = rng.uniform(-0.08, 0.08, 200)
    points = g.p + d[:, None] * g.normal
    np.testing.assert_allclose(cross_track_error(path, points), d, atol=1e-10)
    np.testing.assert_allclose(along_track(path, points), s, atol=1e-8)


def test_projection_tracks_from_a_hint() -> None:
    """With a hint, the projection follows the nearby lap/branch (circle's second lap)."""
    circle = Circle(radius=1.0)
    point = circle.point(1.5 * circle.length) * 1.1
    s = circle.project(point, hint=1.4 * circle.length)
    assert s == pytest.approx(1.5 * circle.length)
    sine = PATHS["sinusoid"]
    target = 7.3
    near = sine.point(target) + 0.02 * sine.geometry(target).normal
    assert sine.project(near, hint=target + 0.3) == pytest.approx(target, abs=1e-9)


def _brute_force_projection(path: Path, point: np.ndarray, lo: float, hi: float) -> float:
    """The closest of 10^5 samples over [lo, hi], then of 4000 samples around it."""
    s = np.linspace(lo, hi, 100_001)
    k = int(np.argmin(np.sum((path.point(s) - point) ** 2, axis=1)))
    fine = np.linspace(s[max(k - 1, 0)], s[min(k + 1, len(s) - 1)], 4001)
    return float(fine[np.argmin(np.sum((path.point(fine) - point) ** 2, axis=1))])


def test_fast_projection_equals_brute_force(path: Path, rng: np.random.Generator) -> None:
    """Hinted (table + expansion) and global projections equal dense sampling to 1e-6;
    the LOS step's point and tangent angle are the curve's at its s."""
    s = rng.uniform(0.1, min(path.length, 6.0) - 0.1, 8)
    g = path.geometry(s)
    points = g.p + rng.uniform(-0.15, 0.15, 8)[:, None] * g.normal
    hint = s + rng.uniform(-0.2, 0.2, 8)
    fast = path.project(points, hint=hint)
    lo, hi = path.default_span()
    whole = path.project(points, span=(lo, hi))
    for k in range(8):
        near = _brute_force_projection(path, points[k], hint[k] - 0.5, hint[k] + 0.5)
        assert fast[k] == pytest.approx(near, abs=1e-6)
        assert path.project(points[k], hint=hint[k]) == pytest.approx(near, abs=1e-6)
        # the LOS step: the same s, and the point and tangent angle of the curve there
        s_k, x_k, y_k, gamma_k = path._track(points[k, 0], points[k, 1], hint[k])
        assert s_k == pytest.approx(near, abs=1e-6)
        g_k = path.geometry(s_k)
        assert (x_k, y_k) == pytest.approx(tuple(g_k.p), abs=1e-9)
        assert gamma_k == pytest.approx(float(g_k.gamma), abs=1e-7)  # kappa'' sigma^3 / 6
        assert whole[k] == pytest.approx(_brute_force_projection(path, points[k], lo, hi),
                                         abs=1e-6)


def test_paths_pickle_small_and_whole(path: Path, rng: np.random.Generator) -> None:
    """A path pickles by its parameters (small, even after projections filled its cache)
    and the copy gives the same reference and projections (worker processes get it)."""
    import pickle

    path.project(np.array([[0.3, 0.2]]), hint=np.array([0.3]))  # fills the hinted cache
    data = pickle.dumps(PathReference(path, Timing(speed=0.1)))
    copy = pickle.loads(data)
    assert len(data) < 2000
    for t in rng.uniform(0.0, 40.0, 5):
        for a, b in zip(PathReference(path, Timing(speed=0.1))(t), copy(t), strict=True):
            np.testing.assert_array_equal(a, b)
    points = rng.uniform(-1.0, 2.0, (4, 2))
    np.testing.assert_array_equal(path.project(points), copy.path.project(points))


def test_hinted_projection_far_along_keeps_its_table_small() -> None:
    """A hint 3 km along a sinusoid moves the sample table there (bounded size, not the
    whole 3 km) and still finds the closest point of a point near the path there."""
    path = PATHS["sinusoid"]
    path.project(np.array([[0.3, 0.2]]), hint=np.array([0.3]))
    target = path.geometry(np.array([3000.0])).p[0] + np.array([0.0, 0.05])
    (sigma,) = path.project(target[None, :], hint=np.array([3000.2]))
    assert len(path.__dict__["_near_table"].p) < 100_000
    fine = np.linspace(2999.0, 3001.0, 200_001)
    brute = fine[np.argmin(np.linalg.norm(path.geometry(fine).p - target, axis=1))]
    assert abs(sigma - brute) < 1e-4


def test_timing_ramp_is_smooth() -> None:
    """The ramp starts at rest, reaches v at T with s'' = 0 there, and s = v (t - T/2) after."""
    timing = Timing(speed=0.2, ramp=3.0, start=1.0)
    s, ds, dds = timing(np.array([0.0, 3.0, 5.0]))
    np.testing.assert_allclose(s, [1.0, 1.3, 1.7])
    np.testing.assert_allclose(ds, [0.0, 0.2, 0.2])
    np.testing.assert_allclose(dds, 0.0, atol=1e-15)
    assert timing(1.5)[2] > 0


# ---------------------------------------------------------------------- path files
def test_toml_and_csv_files_load(tmp_path: FilePath) -> None:
    """TOML waypoints/shapes and CSV (with or without a header) give the paths they name."""
    toml = tmp_path / "loop.toml"
    toml.write_text(f"type = \"waypoints\"\npoints = {[list(p) for p in LOOP]}\nspeed = 0.2\n")
    ref = load_path(toml)
    assert ref.timing.speed == 0.2
    np.testing.assert_allclose(ref.path.point(ref.path.knots_s), LOOP)
    circle = tmp_path / "circle.toml"
    circle.write_text('type = "circle"\nradius = 0.9\nclockwise = true\nramp = 2.0\n')
    ref = load_path(circle, speed=0.05)  # a command-line speed overrides the file
    assert ref.path == Circle(radius=0.9, clockwise=True)
    assert (ref.timing.speed, ref.timing.ramp) == (0.05, 2.0)
    lane = tmp_path / "lane.toml"
    lane.write_text('type = "lane_change"\noffset = -0.2\nlength = 1.5\n')
    assert load_path(lane).path == LaneChange(offset=-0.2, length_x=1.5)
    rows = "\n".join(f"{x},{y}" for x, y in LOOP)
    for text in (rows, "x,y\n" + rows, "x, y\n\n" + rows + "\n"):
        csv = tmp_path / "loop.csv"
        csv.write_text(text)
        np.testing.assert_allclose(load_path(csv).path.points, LOOP)


def test_named_paths() -> None:
    """Names with parameters build the shapes; unknown names and keys are refused."""
    assert load_path("circle", radius=2.0, speed=0.3).path == Circle(radius=2.0)
    assert make_path("lane_change", length=3.0) == LaneChange(length_x=3.0)
    assert isinstance(load_path("sinusoid").path, Sinusoid)
    with pytest.raises(ParameterError, match="unknown path 'hexagon'"):
        load_path("hexagon")
    with pytest.raises(ParameterError, match="unknown parameter 'radious'"):
        load_path("circle", radious=1.0)


BAD_FILES = {
    "one_waypoint.toml": ('type = "waypoints"\npoints = [[0, 0]]\n', "at least two waypoints"),
    "repeated.toml": ('type = "waypoints"\npoints = [[0, 0], [1, 0], [1, 0], [2, 1]]\n',
                      "waypoints 2 and 3 coincide"),
    "radius.toml": ('type = "circle"\nradius = 0.0\n', "radius must be positive"),
    "negative_radius.toml": ('type = "arc"\nradius = -1.0\n', "radius must be positive"),
    "speed.toml": ('type = "line"\nspeed = 0\n', "speed must be positive"),
    "nan.toml": ('type = "sinusoid"\namplitude = nan\n', "amplitude must be finite"),
    "nan_point.toml": ('type = "waypoints"\npoints = [[0, 0], [nan, 1]]\n', "waypoint 2"),
    "syntax.toml": ('type = "circle"\nradius = = 1\n', "not valid TOML"),
    "unknown_key.toml": ('type = "circle"\nradius = 1\ncolour = "red"\n',
                         "unknown key 'colour'"),
    "no_type.toml": ("radius = 1\n", "type is required"),
    "bad_type.toml": ('type = "spiral"\n', "unknown path type 'spiral'"),
    "string_radius.toml": ('type = "circle"\nradius = "big"\n', "radius must be a number"),
    "huge_radius.toml": ('type = "circle"\nradius = 1' + "0" * 400 + "\n", "radius must be finite"),
    "huge_point.toml": ('type = "waypoints"\npoints = [[0, 0], [1' + "0" * 400 + ", 1]]\n",
                        "points must be a list of [x, y] pairs"),
    "flag.toml": ('type = "circle"\nclockwise = 1\n', "clockwise must be true or false"),
    "no_points.toml": ('type = "waypoints"\n', "points is required"),
    "one_row.csv": ("x,y\n0,0\n", "at least two waypoints"),
    "repeated.csv": ("0,0\n0,0\n1,1\n", "waypoints 1 and 2 coincide"),
    "text.csv": ("0,0\n1,one\n", "waypoint 2: not a number pair"),
    "columns.csv": ("0,0,0\n1,1,1\n", "expected two columns"),
    "nan.csv": ("0,0\nnan,1\n", "waypoint 2 is not finite"),
    "binary.csv": (b"\xff\xfe\x00", "not UTF-8"),
    "far_point.toml": ('type = "waypoints"\npoints = [[0, 0], [1e160, 0], [2e160, 1]]\n',
                       "points: waypoint 2 (1e+160, 0) lies beyond +-1e+06 m"),
    "far_point.csv": ("x,y\n0,0\n1,1\n2,-1e7\n", "points: waypoint 3 (2, -1e+07) lies beyond"),
    "deep_points.toml": ('type = "waypoints"\npoints = ' + "[" * 100_000 + "]" * 100_000,
                         "nested deeper than 32 levels"),
    "deep_table.toml": ('type = "line"\nstart = ' + "{a = " * 100_000 + "1" + "}" * 100_000,
                        "nested deeper than 32 levels"),
    "dotted.toml": ('type = "line"\n' + "a." * 100_000 + "a = 1\n",
                    "nested deeper than 32 levels"),
    "tiny_radius.toml": ('type = "circle"\nradius = 1e-300\n', "radius must be at least 1e-06 m"),
    "far_origin.toml": ('type = "sinusoid"\norigin = [0, 1e300]\n',
                        "origin[1] must lie within +-1e+06 m"),
    "fast.toml": ('type = "line"\nspeed = 1e300\n', "speed must be at most 1000 m/s"),
}


@pytest.mark.parametrize("name", list(BAD_FILES))
def test_bad_path_files_are_refused_in_one_line(tmp_path: FilePath, name: str) -> None:
    """Every bad file is one PathFileError line naming the file and the problem."""
    text, expected = BAD_FILES[name]
    target = tmp_path / name
    if isinstance(text, bytes):
        target.write_bytes(text)
    else:
        target.write_text(text)
    with pytest.raises(PathFileError) as info:
        load_path(target)
    message = str(info.value)
    assert "\n" not in message
    assert str(target) in message and expected in message
    assert isinstance(info.value, ParameterError)


def test_missing_and_unsupported_files(tmp_path: FilePath) -> None:
    """A missing file, a folder and a suffix that is neither .toml nor .csv are refused."""
    with pytest.raises(PathFileError, match="no such path file"):
        load_path(tmp_path / "absent.toml")
    folder = tmp_path / "dir.csv"
    folder.mkdir()
    with pytest.raises(PathFileError, match="is a folder"):
        load_path(folder)
    with pytest.raises(ParameterError, match="unknown path"):
        load_path(tmp_path / "path.json")


@pytest.mark.parametrize("kwargs, expected", [
    ({"points": [(0, 0)]}, "at least two waypoints"),
    ({"points": [(0, 0), (0, 0)]}, "coincide"),
    ({"points": [(0, 0), (1, float("nan"))]}, "not finite"),
    ({"points": [(0, 0), (1e160, 0), (2e160, 1)]}, r"waypoint 2 \(1e\+160, 0\) lies beyond"),
    ({"points": [(0, 0), (1, -1.5e6)]}, r"waypoint 2 \(1, -1.5e\+06\) lies beyond"),
])
def test_bad_waypoints(kwargs: dict[str, object], expected: str) -> None:
    """Waypoints built in Python are checked like files' (one ParameterError line)."""
    with pytest.raises(ParameterError, match=expected):
        Waypoints(**kwargs)  # type: ignore[arg-type]


@pytest.mark.parametrize("build, expected", [
    (lambda: Circle(radius=-0.5), "radius must be positive"),
    (lambda: Arc(angle=0.0), "angle must be positive"),
    (lambda: Timing(speed=-0.1), "speed must be positive"),
    (lambda: Timing(ramp=float("inf")), "ramp must be finite"),
    (lambda: Sinusoid(wavelength=0.0), "wavelength must be positive"),
    (lambda: LaneChange(length_x=-1.0), "length must be positive"),
    (lambda: Line(start=(0.0,)), "start must be a point"),
    (lambda: Line(direction=1e300), "direction must lie within"),
    (lambda: Circle(centre=(2e6, 0.0)), r"centre\[0\] must lie within \+-1e\+06 m"),
    (lambda: Circle(start_angle=-1e4), "start_angle must lie within"),
    (lambda: Arc(angle=1e300), "angle must lie within"),
    (lambda: Sinusoid(wavelength=1e-300), "wavelength must be at least 1e-06 m"),
    (lambda: Sinusoid(amplitude=1e300), "amplitude must lie within"),
    (lambda: LaneChange(length_x=1e-300), "length must be at least"),
    (lambda: LaneChange(offset=-1e300), "offset must lie within"),
    (lambda: Timing(speed=1e300), "speed must be at most"),
    (lambda: Timing(start=1e300), "start must lie within"),
])
def test_bad_parameters(build: object, expected: str) -> None:
    """Out-of-domain shape and timing parameters are one ParameterError naming them."""
    with pytest.raises(ParameterError, match=expected):
        build()  # type: ignore[operator]


def test_parameters_at_their_bounds_give_finite_references() -> None:
    """Values at the bounds themselves are accepted and give a finite reference."""
    for path in (Waypoints(points=[(-1e6, -1e6), (1e6, 1e6), (1e6, -1e6)]),
                 Circle(radius=1e-6, centre=(1e6, -1e6)), Arc(radius=1e6, angle=1e3),
                 Sinusoid(amplitude=1e-6, wavelength=1e6, direction=-1e3),
                 LaneChange(offset=1e6, length_x=1e6, start=1e6)):
        reference = PathReference(path, Timing(speed=1e3, start=-1e6))
        for t in (0.0, 1.0, 1e3):
            assert all(np.isfinite(part).all() for part in reference(t)), (path, t)


@pytest.mark.parametrize("name", ["points.csv", "points.toml"])
def test_a_fifo_is_refused_without_blocking(tmp_path: FilePath, name: str) -> None:
    """A FIFO given as a path file is refused at once, in one line naming it."""
    fifo = tmp_path / name
    os.mkfifo(fifo)
    error = raised_without_blocking(lambda: load_path(fifo), "load_path on a FIFO")
    assert isinstance(error, PathFileError)
    assert str(error) == f"{fifo}: is a FIFO, not a regular file: not a path file"


@pytest.mark.parametrize("measure", [along_track, cross_track_error])
def test_distance_arguments_are_checked(measure: object) -> None:
    """A path that is not a Path, points that are not numbers and a span that is not
    (s_min, s_max) are each one ParameterError line naming the argument."""
    points = np.zeros((2, 2))
    for path in (None, "line", [1.0], True, {}):
        with pytest.raises(ParameterError, match=r"^path must be a Path or a PathReference"):
            measure(path, points)  # type: ignore[operator]
    for bad in ("abc", {}, [[1.0, "x"]]):
        with pytest.raises(ParameterError, match=r"^points must be a finite"):
            measure(Line(), bad)  # type: ignore[operator]
    for span in ("ab", [1.0], True, {}, (0.0, "x"), (2.0, 1.0)):
        with pytest.raises(ParameterError, match=r"^span"):
            measure(Circle(), points, span=span)  # type: ignore[operator]
    reference = load_path("line")
    assert measure(reference, points, span=[0.0, 1.0]).shape == (2,)  # type: ignore[operator]


@pytest.mark.parametrize("path", [Line(), Circle(), Sinusoid()], ids=lambda p: p.name)
def test_project_refuses_bad_points_and_hints_in_one_line(path: Path) -> None:
    """Points that are not a finite (..., 2) array and hints that are not finite arc lengths
    (one, or one per point) are one ParameterError line naming the argument, whether the
    shape projects in closed form or by its table; no points project to no arc lengths."""
    points = np.zeros((2, 2))
    for bad in ("abc", [[1.0, "x"]], np.zeros((2, 3)), [[np.nan, 0.0]]):
        with pytest.raises(ParameterError, match=r"^points must be a finite"):
            path.project(bad)
    for hint in ("a", [1.0, 2.0, 3.0], np.nan, {}):
        with pytest.raises(ParameterError, match=r"^hint must be finite"):
            path.project(points, hint=hint)
    assert path.project(np.zeros((0, 2)), hint=0.1).shape == (0,)
    assert path.project(np.zeros((3, 4, 2)), hint=np.zeros((3, 4))).shape == (3, 4)
