"""Tests of fusion_planner.core.simulation.world: kinematics, laser, collisions, obstacles, determinism."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fusion_planner.core.errors import InvalidInput
from fusion_planner.core.grid import GridMap
from fusion_planner.core.simulation.world import (
    BounceMotion, Circle, MovingObstacle, RandomWalkMotion, Rectangle, RobotSpec, ScanConfig,
    StaticScene, WaypointMotion, World, integrate_unicycle, ray_box_distances,
    ray_circle_distances, ray_grid_distances, rasterise_obstacles)
from fusion_planner.core.simulation import ray_kernel

RES = 0.1


def empty_grid(width_m=10.0, height_m=8.0, origin=(0.0, 0.0, 0.0)):
    return GridMap(np.zeros((int(round(height_m / RES)), int(round(width_m / RES))), bool), RES, origin)


def grid_with_wall_at_x(x_wall, width_m=10.0, height_m=8.0):
    """Empty room with an occupied column of cells starting at x = x_wall."""
    occ = np.zeros((int(round(height_m / RES)), int(round(width_m / RES))), bool)
    occ[:, int(round(x_wall / RES))] = True
    return GridMap(occ, RES)


def make_world(grid=None, pose=(2.0, 3.0, 0.0), radius=0.2, unknown=(), moving=(), scan=None,
               seed=0, **robot):
    return World(grid or empty_grid(), RobotSpec(radius=radius, **robot), pose, unknown, moving,
                 scan or ScanConfig(beams=360), seed=seed)


# -- kinematics ---------------------------------------------------------------------

def test_straight_line_motion():
    pose = integrate_unicycle((1.0, 2.0, math.pi / 6), 0.5, 0.0, 2.0)
    assert np.allclose(pose, [1.0 + math.cos(math.pi / 6), 2.0 + math.sin(math.pi / 6), math.pi / 6])


def test_quarter_circle_arc():
    # v / omega = 2 / pi: a quarter circle of that radius about (0, 2/pi)
    pose = integrate_unicycle((0.0, 0.0, 0.0), 1.0, math.pi / 2, 1.0)
    r = 2 / math.pi
    assert np.allclose(pose, [r, r, math.pi / 2])


def test_full_circle_returns_to_start():
    pose = np.array([3.0, -1.0, 0.7])
    for _ in range(40):
        pose = integrate_unicycle(pose, 0.8, 2 * math.pi / 4.0, 0.1)  # 4 s per turn
    assert np.allclose(pose, [3.0, -1.0, 0.7], atol=1e-9)


@settings(max_examples=60, deadline=None)
@given(v=st.floats(-1.0, 1.0), omega=st.floats(-3.0, 3.0), yaw=st.floats(-math.pi, math.pi),
       steps=st.integers(1, 20))
def test_arc_integration_is_exact_under_subdivision(v, omega, yaw, steps):
    one = integrate_unicycle((0.0, 0.0, yaw), v, omega, 1.0)
    many = np.array([0.0, 0.0, yaw])
    for _ in range(steps):
        many = integrate_unicycle(many, v, omega, 1.0 / steps)
    assert np.allclose(one[:2], many[:2], atol=1e-9)
    assert math.isclose(math.cos(one[2]), math.cos(many[2]), abs_tol=1e-9)
    assert math.isclose(math.sin(one[2]), math.sin(many[2]), abs_tol=1e-9)


def test_step_applies_speed_turn_and_acceleration_limits():
    world = make_world(pose=(5.0, 4.0, 0.0), max_speed=0.5, max_accel=1.0, max_omega=1.0)
    world.step(5.0, 10.0, 0.1)
    assert world.velocity[0] == pytest.approx(0.1)      # accel: 1 m/s^2 * 0.1 s
    assert world.velocity[1] == pytest.approx(1.0)      # turn-rate cap
    for _ in range(20):
        world.step(5.0, 0.0, 0.1)
    assert world.velocity[0] == pytest.approx(0.5)      # speed cap
    assert world.time == pytest.approx(2.1)


def test_step_rejects_bad_command():
    world = make_world()
    with pytest.raises(InvalidInput):
        world.step(float('nan'), 0.0, 0.1)
    with pytest.raises(InvalidInput):
        world.step(0.1, 0.0, 0.0)


# -- laser ----------------------------------------------------------------------------

def test_scan_of_a_wall_matches_analytic_distances():
    x_wall = 6.0
    world = make_world(grid_with_wall_at_x(x_wall), pose=(2.05, 3.02, 0.3),
                       scan=ScanConfig(beams=720, range_max=20.0))
    scan = world.scan()
    world_angles = 0.3 + scan.angles
    toward = np.abs(world_angles) < math.radians(30)      # these beams hit the wall first
    expected = (x_wall - 2.05) / np.cos(world_angles[toward])
    assert np.allclose(scan.ranges[toward], expected, atol=1e-9)


def test_scan_of_the_map_edge_in_an_empty_room():
    world = make_world(empty_grid(10.0, 8.0), pose=(3.0, 4.0, 0.0), scan=ScanConfig(beams=4))
    # beams at -pi, -pi/2, 0, pi/2: left edge 3 m, bottom 4 m, right 7 m, top 4 m
    assert np.allclose(world.scan().ranges, [3.0, 4.0, 7.0, 4.0])


def test_scan_of_a_circle_matches_analytic_distances():
    centre, radius = np.array([6.0, 4.0]), 1.0
    world = make_world(empty_grid(20.0, 8.0), pose=(2.0, 4.3, 0.0),
                       unknown=[Circle(tuple(centre), radius)],
                       scan=ScanConfig(beams=720, range_max=15.0))
    scan = world.scan()
    p = np.array([2.0, 4.3])
    d = np.stack([np.cos(scan.angles), np.sin(scan.angles)], axis=1)
    w = p - centre
    b = d @ w
    disc = b * b - (w @ w - radius ** 2)
    with np.errstate(invalid='ignore'):
        entry = -b - np.sqrt(disc)
    hits = (disc >= 0) & (entry > 0)                     # beams toward the circle
    assert hits.sum() > 10
    expected = entry[hits]
    assert np.allclose(scan.ranges[hits], expected, atol=1e-9)
    # the hit points lie on the circle
    on_circle = np.isfinite(scan.ranges) & hits
    pts = p + d[on_circle] * scan.ranges[on_circle, None]
    assert np.allclose(np.hypot(*(pts - centre).T), radius, atol=1e-9)


def test_scan_sees_rectangles_and_moving_obstacles():
    mover = MovingObstacle(0.5, BounceMotion((2.0, 7.0), (0.0, 0.0)))
    world = make_world(empty_grid(10.0, 10.0), pose=(2.0, 2.0, 0.0),
                       unknown=[Rectangle((5.0, 1.0), (6.0, 3.0))], moving=[mover],
                       scan=ScanConfig(beams=4))
    ranges = world.scan().ranges  # -pi, -pi/2, 0, pi/2
    assert np.allclose(ranges, [2.0, 2.0, 3.0, 4.5])


def test_scan_range_limits_follow_rep_117():
    world = make_world(empty_grid(10.0, 10.0), pose=(5.0, 5.0, 0.0),
                       scan=ScanConfig(beams=8, range_min=0.05, range_max=3.0))
    scan = world.scan()
    assert np.all(np.isposinf(scan.ranges))   # every wall is farther than 3 m
    assert scan.points.shape == (0, 2)
    close = make_world(empty_grid(10.0, 10.0), pose=(5.0, 5.0, 0.0), radius=0.01,
                       unknown=[Circle((5.03, 5.0), 0.0101)],
                       scan=ScanConfig(beams=4, range_min=0.05, range_max=3.0))
    ranges = close.scan().ranges
    assert np.isneginf(ranges[2])             # hit at 0.0199 m < range_min


def test_scan_noise_is_seeded():
    def ranges(seed):
        world = make_world(pose=(2.0, 3.0, 0.0), scan=ScanConfig(beams=90, noise_std=0.02), seed=seed)
        return world.scan().ranges
    exact = make_world(pose=(2.0, 3.0, 0.0), scan=ScanConfig(beams=90)).scan().ranges
    a, b, c = ranges(3), ranges(3), ranges(4)
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)
    finite = np.isfinite(exact)
    assert finite.sum() > 45
    assert 0.005 < np.std(a[finite] - exact[finite]) < 0.05


def test_scan_hit_points_are_map_frame_endpoints():
    world = make_world(grid_with_wall_at_x(7.0), pose=(3.0, 4.0, 1.0), scan=ScanConfig(beams=360))
    scan = world.scan()
    valid = np.isfinite(scan.ranges)
    angles = 1.0 + scan.angles[valid]
    unit = np.stack([np.cos(angles), np.sin(angles)], 1)
    expected = np.array([3.0, 4.0]) + scan.ranges[valid, None] * unit
    assert np.allclose(scan.points, expected)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000))
def test_grid_ray_cast_agrees_with_analytic_cell_boxes(seed):
    # reference: every occupied cell as an exact box (slab test), plus the grid edge
    rng = np.random.default_rng(seed)
    occ = rng.random((30, 40)) < 0.08
    origin = rng.uniform([1, 1], [39, 29])
    occ[int(origin[1]), int(origin[0])] = False
    angles = rng.uniform(-math.pi, math.pi, 50)
    dirs = np.stack([np.cos(angles), np.sin(angles)], 1)
    got = ray_grid_distances(occ, origin, dirs, 80.0)
    rows, cols = np.nonzero(occ)
    with np.errstate(divide='ignore'):
        exit_x = np.where(dirs[:, 0] > 0, (40 - origin[0]) / dirs[:, 0], -origin[0] / dirs[:, 0])
        exit_y = np.where(dirs[:, 1] > 0, (30 - origin[1]) / dirs[:, 1], -origin[1] / dirs[:, 1])

    def expected(shrink):
        mins = np.stack([cols + shrink, rows + shrink], 1).astype(float)
        maxs = np.stack([cols + 1 - shrink, rows + 1 - shrink], 1).astype(float)
        return np.minimum(ray_box_distances(origin, dirs, mins, maxs), np.minimum(exit_x, exit_y))

    # a ray only touching a corner is not a hit: the exact answer lies between
    # the boxes as they are and the boxes shrunk by 1e-7 cells
    assert np.all(got >= expected(0.0) - 1e-9), seed
    assert np.all(got <= expected(1e-7) + 1e-9), seed


@pytest.mark.skipif(not ray_kernel.available(), reason='needs numba (the fast extra)')
@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), max_distance=st.sampled_from([3.0, 12.5, 80.0]))
def test_compiled_ray_cast_equals_the_array_version(seed, max_distance):
    rng = np.random.default_rng(seed)
    occ = rng.random((30, 40)) < 0.08
    origin = rng.uniform([1, 1], [39, 29])
    occ[int(origin[1]), int(origin[0])] = False
    # random rays and the axis-aligned and diagonal ones (crossings in ties, zero components)
    angles = np.concatenate([rng.uniform(-math.pi, math.pi, 50), np.arange(-4, 4) * math.pi / 4])
    dirs = np.stack([np.cos(angles), np.sin(angles)], 1)
    dirs[np.abs(dirs) < 1e-12] = 0.0
    compiled = ray_grid_distances(occ, origin, dirs, max_distance)
    arrays = ray_grid_distances(occ, origin, dirs, max_distance, compiled=False)
    assert np.array_equal(compiled, arrays), seed


def test_ray_helpers_handle_inside_and_miss():
    origin = np.array([0.0, 0.0])
    dirs = np.array([[1.0, 0.0], [0.0, 1.0]])
    inside = ray_circle_distances(origin, dirs, np.array([[0.0, 0.0]]), np.array([1.0]))
    assert np.array_equal(inside, [0.0, 0.0])
    miss = ray_box_distances(origin, dirs, np.array([[2.0, 2.0]]), np.array([[3.0, 3.0]]))
    assert np.all(np.isinf(miss))


def test_scan_on_a_rotated_map():
    # the same room, its origin rotated by 90 degrees: the wall distances rotate with it
    grid = empty_grid(10.0, 8.0, origin=(0.0, 0.0, math.pi / 2))  # covers x in [-8, 0], y in [0, 10]
    world = make_world(grid, pose=(-3.0, 2.0, 0.0), scan=ScanConfig(beams=4))
    assert np.allclose(world.scan().ranges, [5.0, 2.0, 3.0, 8.0])


# -- collisions and clearance ----------------------------------------------------------

def test_disc_square_collision_is_exact_at_a_corner():
    occ = np.zeros((40, 40), bool)
    occ[20, 20] = True                                   # square [2.0, 2.1] x [2.0, 2.1]
    scene = StaticScene(GridMap(occ, RES))
    r = 0.3
    corner = np.array([2.0, 2.0])
    direction = np.array([-1.0, -1.0]) / math.sqrt(2)
    assert scene.disc_collides(corner + direction * (r - 1e-6), r)
    assert not scene.disc_collides(corner + direction * (r + 1e-6), r)
    # along a face, not a corner
    assert scene.disc_collides((2.05, 2.0 - r + 1e-6), r)
    assert not scene.disc_collides((2.05, 2.0 - r - 1e-6), r)


def test_collision_with_circles_rectangles_movers_and_the_edge():
    mover = MovingObstacle(0.3, BounceMotion((8.0, 2.0), (0.0, 0.0)))
    world = make_world(pose=(2.0, 2.0, 0.0),
                       unknown=[Circle((4.0, 4.0), 0.5), Rectangle((6.0, 6.0), (7.0, 7.0))],
                       moving=[mover])
    assert not world.in_collision()
    assert world.in_collision((4.0, 3.35))            # circle: 0.65 < 0.5 + 0.2
    assert not world.in_collision((4.0, 3.25))
    assert world.in_collision((5.85, 6.5))             # rectangle face at x = 6
    assert world.in_collision((7.55, 2.0))             # mover: 0.45 < 0.5
    assert world.in_collision((0.1, 4.0))              # map edge
    assert not world.in_collision((9.75, 4.0))


def test_clearance_is_the_gap_to_the_nearest_obstacle():
    world = make_world(grid_with_wall_at_x(5.0, 10.0, 8.0), pose=(3.0, 4.0, 0.0), radius=0.25)
    assert world.clearance() == pytest.approx(5.0 - 3.0 - 0.25)
    world = make_world(pose=(5.0, 4.0, 0.0), radius=0.25, unknown=[Circle((6.0, 4.0), 0.4)])
    assert world.clearance() == pytest.approx(1.0 - 0.4 - 0.25)


def test_robot_cannot_enter_a_wall_and_a_long_push_is_one_contact():
    world = make_world(grid_with_wall_at_x(5.0), pose=(4.5, 4.0, 0.0), radius=0.2)
    for _ in range(30):
        world.step(0.5, 0.0, 0.1)
    assert world.pose[0] < 5.0 - 0.2                    # never inside the wall
    assert not world.in_collision()
    assert world.contact_events == 1
    for _ in range(10):
        world.step(-0.5, 0.0, 0.1)                       # back off, then bump again
    assert not world.in_contact
    for _ in range(30):
        world.step(0.5, 0.0, 0.1)
    assert world.contact_events == 2


def test_a_mover_walking_into_the_robot_is_a_contact():
    mover = MovingObstacle(0.3, BounceMotion((6.0, 4.0), (-0.5, 0.0)))
    world = make_world(pose=(4.0, 4.0, 0.0), moving=[mover])
    for _ in range(40):
        world.step(0.0, 0.0, 0.1)
    assert world.contact_events == 1
    assert world.clearance() == 0.0


# -- moving obstacles -------------------------------------------------------------------

def test_bounce_stays_in_the_map_and_reflects_off_walls():
    mover = MovingObstacle(0.3, BounceMotion((5.0, 4.0), (0.7, 0.45)))
    world = make_world(pose=(1.0, 1.0, 0.0), unknown=[Rectangle((2.0, 5.0), (3.0, 6.0))], moving=[mover])
    scene = world.static
    xs = []
    for _ in range(600):
        world.step(0.0, 0.0, 0.1)
        p = world.obstacle_positions()[0]
        assert not scene.disc_collides(p, 0.3 - 1e-9)
        xs.append(p)
        tracked = world.tracked_obstacles()[0]
        assert math.hypot(tracked[2], tracked[3]) == pytest.approx(math.hypot(0.7, 0.45))
    xs = np.array(xs)
    assert xs[:, 0].max() > 9.0 and xs[:, 0].min() < 1.0  # it crossed the room both ways


def test_people_walking_at_each_other_do_not_walk_through_each_other():
    """Random walkers and bouncing people reflect off one another (two overlapping discs
    would be one object to a laser); a waypoint walker keeps to its schedule regardless."""
    crowd = [MovingObstacle(0.25, RandomWalkMotion((x, 4.0), 0.6, 1.0)) for x in (3.0, 5.0, 7.0)]
    crowd += [MovingObstacle(0.3, BounceMotion((5.0, 2.0), (0.0, 0.6))),
              MovingObstacle(0.25, WaypointMotion(((1.0, 3.0), (9.0, 3.0)), 0.5))]
    world = make_world(pose=(0.5, 0.5, 0.0), moving=crowd, seed=3)
    radii = np.array([m.radius for m in crowd])
    closest = np.inf
    for i in range(600):
        world.step(0.0, 0.0, 0.1)
        centres = world.obstacle_positions()
        gaps = np.hypot(*(centres[:, None] - centres[None]).transpose(2, 0, 1)) \
            - radii[:, None] - radii[None]
        free = gaps[:4, :4][np.triu_indices(4, 1)]
        closest = min(closest, free.min())
        assert free.min() > -1e-9, f'step {i}: {free.min()}'
        t = world.time % 32.0                            # the waypoint loop: 16 m at 0.5 m/s
        expected = (1.0 + 0.5 * t, 3.0) if t <= 16.0 else (9.0 - 0.5 * (t - 16.0), 3.0)
        assert np.allclose(centres[4], expected, atol=1e-6)
    assert closest < 0.1                                 # they did meet


def test_waypoint_loop_is_periodic_and_on_the_polyline():
    pts = ((1.0, 1.0), (5.0, 1.0), (5.0, 4.0))
    mover = MovingObstacle(0.2, WaypointMotion(pts, 0.5))
    world = make_world(pose=(8.0, 6.0, 0.0), moving=[mover])
    perimeter = 4.0 + 3.0 + 5.0
    steps = int(round(perimeter / 0.5 / 0.1))           # one lap
    for i in range(steps):
        world.step(0.0, 0.0, 0.1)
        if i == 9:                                       # t = 1 s: 0.5 m along the first leg
            assert np.allclose(world.tracked_obstacles()[0], [1.5, 1.0, 0.5, 0.0, 0.2])
    assert np.allclose(world.obstacle_positions()[0], pts[0], atol=1e-9)


def test_random_walk_depends_on_the_seed_only():
    def track(seed):
        mover = MovingObstacle(0.2, RandomWalkMotion((5.0, 4.0), 0.4, 1.0))
        world = make_world(pose=(1.0, 1.0, 0.0), moving=[mover], seed=seed)
        out = []
        for _ in range(100):
            world.step(0.0, 0.0, 0.1)
            out.append(world.tracked_obstacles()[0])
        return np.array(out)
    a, b, c = track(1), track(1), track(2)
    assert np.array_equal(a, b)
    assert not np.allclose(a, c)
    assert np.allclose(np.hypot(a[:, 2], a[:, 3]), 0.4)


def test_tracked_obstacles_shape():
    assert make_world().tracked_obstacles().shape == (0, 5)
    movers = [MovingObstacle(0.2, BounceMotion((5.0, 4.0), (0.1, 0.0))),
              MovingObstacle(0.3, WaypointMotion(((6.0, 6.0), (7.0, 6.0)), 0.2))]
    tracked = make_world(moving=movers).tracked_obstacles()
    assert tracked.shape == (2, 5)
    assert np.allclose(tracked[:, 4], [0.2, 0.3])


# -- determinism and input checks ---------------------------------------------------------

def test_same_seed_same_run():
    def run(seed):
        movers = [MovingObstacle(0.25, RandomWalkMotion((6.0, 5.0), 0.3, 0.8)),
                  MovingObstacle(0.25, BounceMotion((3.0, 6.0), (0.2, -0.1)))]
        world = make_world(pose=(2.0, 2.0, 0.3), moving=movers, seed=seed,
                           scan=ScanConfig(beams=90, noise_std=0.01))
        poses, scans = [], []
        for k in range(150):
            scan = world.scan()
            scans.append(scan.ranges)
            world.step(0.4, 0.6 * math.sin(0.1 * k), 0.1)
            poses.append(world.pose.copy())
        return np.array(poses), np.array(scans)
    (p1, s1), (p2, s2) = run(5), run(5)
    assert np.array_equal(p1, p2) and np.array_equal(s1, s2)


def test_bad_arguments_are_refused():
    with pytest.raises(InvalidInput):
        World(np.zeros((3, 3)), RobotSpec(0.2), (0, 0, 0))
    with pytest.raises(InvalidInput):
        make_world(pose=(1.0, float('nan'), 0.0))
    with pytest.raises(InvalidInput):
        make_world(unknown=['not an obstacle'])


def test_rasterised_true_map_covers_the_unknown_obstacles():
    grid = empty_grid(10.0, 8.0)
    truth = rasterise_obstacles(grid, [Circle((3.0, 3.0), 0.5)], [Rectangle((6.0, 2.0), (7.0, 2.5))])
    assert truth.occupied[30, 30] and truth.occupied[22, 65]
    assert not truth.occupied[30, 40]
    # every cell a circle point falls in is occupied (conservative raster)
    angles = np.linspace(0, 2 * math.pi, 200)
    boundary = np.array([3.0, 3.0]) + 0.499 * np.stack([np.cos(angles), np.sin(angles)], 1)
    cells = truth.cell_of(boundary)
    assert truth.occupied[cells[:, 0], cells[:, 1]].all()


def test_a_720_beam_scan_sees_the_wall_the_boxes_and_the_people():
    occ = np.zeros((200, 200), bool)
    occ[50:60, 50:150] = True
    world = make_world(GridMap(occ, RES), pose=(10.0, 10.0, 0.0),
                       unknown=[Circle((14.0, 10.0), 0.5)] * 5,
                       moving=[MovingObstacle(0.3, BounceMotion((5.0, 15.0), (0.2, 0.0)))] * 5,
                       scan=ScanConfig(beams=720, range_max=12.0))
    scan = world.scan()
    assert scan.ranges.shape == (720,)
    ahead = np.abs(scan.angles) < 0.02  # the boxes at 4 m, radius 0.5 m
    assert ahead.any() and np.allclose(scan.ranges[ahead], 3.5, atol=0.02)


@pytest.mark.parametrize('build', [
    lambda: Circle((0.0, 0.0), -1.0),
    lambda: Circle((0.0, float('nan')), 1.0),
    lambda: Rectangle((1.0, 1.0), (0.5, 2.0)),
    lambda: WaypointMotion(((0.0, 0.0),), 1.0),
    lambda: RandomWalkMotion((0.0, 0.0), -0.1, 0.5),
    lambda: MovingObstacle(0.0, BounceMotion((0.0, 0.0), (0.0, 0.0))),
    lambda: MovingObstacle(0.2, 'teleport'),
    lambda: RobotSpec(radius=0.0),
    lambda: ScanConfig(beams=0),
    lambda: ScanConfig(fov=7.0),
    lambda: ScanConfig(range_min=2.0, range_max=1.0),
])
def test_descriptions_validate_their_fields(build):
    with pytest.raises(InvalidInput):
        build()


def test_contacts_are_attributed_to_movers_or_static_obstacles():
    mover = MovingObstacle(0.3, BounceMotion((6.0, 4.0), (-0.5, 0.0)))
    world = make_world(grid_with_wall_at_x(2.0), pose=(4.0, 4.0, 0.0), moving=[mover])
    for _ in range(40):
        world.step(0.0, 0.0, 0.1)           # the mover walks into the robot
    assert world.contact_events == 1 and world.moving_contact_events == 1
    (event,) = world.contacts
    assert event.person == 0 and event.robot_speed_mps == 0.0 and event.approach is None
    assert event.escape and not event.passive      # standing in the open: it could step aside
    assert event.position == tuple(world.pose[:2]) and 0.0 < event.time_s <= world.time
    world = make_world(grid_with_wall_at_x(5.0), pose=(4.5, 4.0, 0.0))
    for _ in range(30):
        world.step(0.5, 0.0, 0.1)           # the robot drives into the wall
    assert world.contact_events == 1 and world.moving_contact_events == 0
    (event,) = world.contacts
    assert event.person is None and event.escape is None and not event.passive
    assert event.robot_speed_mps == pytest.approx(0.5)
