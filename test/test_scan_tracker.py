"""The scan tracker on synthetic scans: crossings, passings, occlusion, clutter, bad scans."""

import math

import numpy as np
import pytest

from fusion_planner.core.errors import InvalidInput
from fusion_planner.core.grid import GridMap
from fusion_planner.core.local_planning.scan_segments import map_explained_mask, segment_scan
from fusion_planner.core.local_planning.scan_tracker import ScanTracker, TrackerParams
from fusion_planner.core.simulation.world import (
    Circle, Rectangle, RobotSpec, ScanConfig, ray_circle_distances, World)

BEAMS = 720
ANGLES = ScanConfig(beams=BEAMS).angles()
DIRECTIONS = np.stack([np.cos(ANGLES), np.sin(ANGLES)], axis=1)
DT = 0.1
RADIUS = 0.3


def open_map(size_cells=200, pillar=None):
    """A walled square map of 0.1 m cells, optionally with a square pillar (row, col slices)."""
    occupied = np.zeros((size_cells, size_cells), bool)
    occupied[0, :] = occupied[-1, :] = occupied[:, 0] = occupied[:, -1] = True
    if pillar is not None:
        occupied[pillar] = True
    return GridMap(occupied, resolution=0.1)


def scan_of(grid, origin, centres, radius=RADIUS):
    """Ranges from a laser at ``origin`` (yaw 0) to the map and some circles."""
    world = World(grid, RobotSpec(radius=0.1), origin, scan_config=ScanConfig(beams=BEAMS,
                                                                              range_max=12.0))
    ranges = world.scan().ranges
    if len(centres):
        circles = ray_circle_distances(np.asarray(origin[:2], float), DIRECTIONS,
                                       np.asarray(centres, float), np.full(len(centres), radius))
        ranges = np.minimum(ranges, circles)
    return ranges


def run(tracker, grid, origin, positions, radius=RADIUS):
    """Feed scans of walkers at ``positions`` (T, K, 2), one every DT; reports per step.

    ``radius`` [m]: of every walker, or one per walker (K,).
    """
    reports = []
    for k, centres in enumerate(positions):
        verdict = tracker.update(ANGLES, scan_of(grid, origin, centres, radius), origin, k * DT)
        assert verdict.accepted, verdict.reason
        reports.append(tracker.report())
    return reports


def segments_of(grid, ranges, origin, angles=ANGLES):
    """The tracker's object candidates of one scan, with its default parameters."""
    p = TrackerParams()
    return segment_scan(angles, ranges, origin, grid, map_explained_mask(grid, p.map_tolerance),
                        p.cluster_gap, p.min_points, p.split_depth)


def walled_map():
    """:func:`open_map` with a block at x 6-8 m, y 10.5-14 m."""
    return open_map(pillar=(slice(105, 140), slice(60, 80)))


def test_walker_crossing_is_tracked_with_its_velocity():
    grid = open_map()
    origin = np.array([3.0, 10.0, 0.0])
    t = np.arange(40) * DT
    walker = np.stack([np.full_like(t, 8.0), 7.0 + 1.0 * t], axis=1)[:, None, :]
    reports = run(ScanTracker(grid), grid, origin, walker)
    assert all(len(r.ids) == 0 for r in reports[:2])        # no velocity from one scan
    first_report = next(k for k, r in enumerate(reports) if len(r.ids))
    assert first_report * DT <= 0.6
    for k, report in enumerate(reports[first_report + 5:], start=first_report + 5):
        assert report.ids.tolist() == [reports[first_report].ids[0]]
        x, y, vx, vy = report.states[0]
        assert math.hypot(x - walker[k, 0, 0], y - walker[k, 0, 1]) < 0.15
        assert math.hypot(vx - 0.0, vy - 1.0) < 0.2
        assert 0.2 <= report.radii[0] <= 0.45
        assert np.all(np.linalg.eigvalsh(report.covariances[0]) > 0)


def test_two_walkers_passing_each_other_keep_their_tracks():
    grid = open_map()
    origin = np.array([3.0, 10.0, 0.0])
    t = np.arange(60) * DT
    up = np.stack([np.full_like(t, 7.6), 7.0 + 0.9 * t], axis=1)
    down = np.stack([np.full_like(t, 8.6), 13.0 - 0.9 * t], axis=1)
    reports = run(ScanTracker(grid), grid, origin, np.stack([up, down], axis=1))
    final = reports[-1]
    assert len(final.ids) == 2
    by_id = {}
    for report in reports[10:]:
        for track_id, state in zip(report.ids, report.states):
            by_id.setdefault(int(track_id), []).append(state)
    assert len(by_id) == 2, 'each walker keeps one track through the passing'
    signs = sorted(np.sign(np.mean([s[3] for s in states])) for states in by_id.values())
    assert signs == [-1.0, 1.0]
    for states in by_id.values():
        vy = np.array([s[3] for s in states])
        assert np.all(np.abs(np.abs(vy) - 0.9) < 0.3)


def test_walker_hidden_by_a_pillar_is_tracked_again_when_it_reappears():
    # pillar 0.4 m wide at x = 6.0..6.4, y = 9.8..10.2 between the laser and the walker's line
    grid = open_map(pillar=(slice(98, 102), slice(60, 64)))
    origin = np.array([3.0, 10.0, 0.0])
    t = np.arange(50) * DT
    walker = np.stack([np.full_like(t, 9.0), 8.0 + 1.0 * t], axis=1)[:, None, :]
    tracker = ScanTracker(grid)
    reports = run(tracker, grid, origin, walker)
    hidden = [k for k in range(len(t))
              if not np.isfinite(scan_of(grid, origin, walker[k])[BEAMS // 2]) or
              scan_of(grid, origin, walker[k])[BEAMS // 2] < 4.0]
    assert hidden, 'the pillar must hide the walker for a while'
    last = reports[-1]
    assert len(last.ids) == 1
    assert math.hypot(*(last.states[0, :2] - walker[-1, 0])) < 0.15
    assert abs(last.states[0, 3] - 1.0) < 0.2
    # while hidden, it coasts on at its velocity instead of vanishing
    during = reports[hidden[len(hidden) // 2]]
    assert len(during.ids) == 1
    assert during.states[0, 1] == pytest.approx(walker[hidden[len(hidden) // 2], 0, 1], abs=0.3)


def test_static_unknown_obstacles_stay_scan_points_while_the_robot_drives():
    grid = open_map()
    circles = [Circle((8.0, 8.5), 0.3), Circle((9.0, 12.0), 0.25), Circle((12.0, 10.0), 0.4)]
    tracker = ScanTracker(grid)
    for k in range(80):
        origin = np.array([2.0 + 0.1 * k, 10.0, 0.0])
        world = World(grid, RobotSpec(radius=0.1), origin, unknown_obstacles=circles,
                      scan_config=ScanConfig(beams=BEAMS, range_max=12.0))
        assert tracker.update(ANGLES, world.scan().ranges, origin, k * DT).accepted
        assert len(tracker.report().ids) == 0


def test_walls_of_the_known_map_are_not_objects():
    grid = open_map(pillar=(slice(80, 120), slice(120, 124)))
    tracker = ScanTracker(grid)
    origin = np.array([5.0, 10.0, 0.3])
    for k in range(20):
        assert tracker.update(ANGLES, scan_of(grid, origin, []), origin, k * DT).accepted
    assert len(tracker._x) == 0


def test_the_same_scans_give_the_same_tracks():
    grid = open_map()
    origin = np.array([3.0, 10.0, 0.0])
    t = np.arange(30) * DT
    walkers = np.stack([np.stack([8.0 - 0.5 * t, 7.0 + 0.8 * t], axis=1),
                        np.stack([6.0 + 0.3 * t, 13.0 - 0.6 * t], axis=1)], axis=1)
    a = run(ScanTracker(grid), grid, origin, walkers)[-1]
    b = run(ScanTracker(grid), grid, origin, walkers)[-1]
    assert np.array_equal(a.ids, b.ids) and np.array_equal(a.states, b.states)
    assert np.array_equal(a.covariances, b.covariances)


@pytest.mark.parametrize('bad, reason', [
    (dict(ranges=np.full(BEAMS - 1, 3.0)), 'as many ranges'),
    (dict(ranges=np.zeros(0), angles=np.zeros(0)), 'as many ranges'),
    (dict(angles=np.full(BEAMS, np.nan)), 'angles must be finite'),
    (dict(origin=[np.nan, 0.0, 0.0]), 'laser pose'),
    (dict(origin=[1.0, 2.0]), 'laser pose'),
    (dict(time=math.inf), 'time must be finite'),
    (dict(time=0.5), 'not newer'),
    (dict(time=1.0), 'not newer'),
    (dict(ranges='abc'), 'not numeric'),
])
def test_bad_scans_are_refused_and_leave_the_tracks_alone(bad, reason):
    grid = open_map()
    origin = np.array([3.0, 10.0, 0.0])
    tracker = ScanTracker(grid)
    t = np.arange(11) * DT
    run(tracker, grid, origin, np.stack([np.full_like(t, 8.0), 8.0 + t], axis=1)[:, None, :])
    before = tracker.report()
    scan = dict(angles=ANGLES, ranges=np.full(BEAMS, 3.0), origin=origin, time=1.0)
    scan.update(bad)
    verdict = tracker.update(**scan)
    assert not verdict.accepted and reason in verdict.reason
    after = tracker.report()
    assert np.array_equal(before.states, after.states) and np.array_equal(before.ids, after.ids)


def test_nan_and_infinite_ranges_are_no_returns():
    grid = open_map()
    origin = np.array([3.0, 10.0, 0.0])
    tracker = ScanTracker(grid)
    t = np.arange(12) * DT
    walker = np.stack([np.full_like(t, 8.0), 8.0 + t], axis=1)[:, None, :]
    run(tracker, grid, origin, walker)
    ranges = scan_of(grid, origin, walker[-1] + [0.0, 0.1])
    ranges[::3] = np.nan
    ranges[1::7] = -np.inf
    assert tracker.update(ANGLES, ranges, origin, 1.2).accepted
    assert len(tracker.report().ids) == 1
    verdict = tracker.update(ANGLES, np.full(BEAMS, np.inf), origin, 1.3)
    assert verdict.accepted and verdict.reason == 'no returns'
    assert len(tracker.report().ids) == 1               # coasting
    for k in range(8):
        tracker.update(ANGLES, np.full(BEAMS, np.nan), origin, 1.4 + k * DT)
    assert len(tracker.report().ids) == 0               # lost after coast_time


def test_report_predicts_ahead_along_the_velocity():
    grid = open_map()
    origin = np.array([3.0, 10.0, 0.0])
    tracker = ScanTracker(grid)
    t = np.arange(15) * DT
    run(tracker, grid, origin, np.stack([np.full_like(t, 8.0), 8.0 + t], axis=1)[:, None, :])
    now, later = tracker.report(), tracker.report(time=tracker.time + 0.5)
    assert later.states[0, 1] - now.states[0, 1] == pytest.approx(0.5 * now.states[0, 3])


def test_bad_parameters_are_refused():
    with pytest.raises(InvalidInput, match='gate'):
        TrackerParams(gate=-1.0)
    with pytest.raises(InvalidInput, match='confirm_hits'):
        TrackerParams(confirm_hits=0)
    with pytest.raises(InvalidInput, match='size_ratio'):
        TrackerParams(size_ratio=1.0)
    with pytest.raises(InvalidInput, match='stop_time'):
        TrackerParams(stop_time=-0.1)
    with pytest.raises(InvalidInput, match='split_depth'):
        TrackerParams(split_depth=0.0)
    with pytest.raises(InvalidInput, match='turn_window'):
        TrackerParams(turn_window=0.0)
    with pytest.raises(InvalidInput, match='turn_prior'):
        TrackerParams(turn_prior=float('nan'))


def test_a_slow_walker_is_a_tentative_mover_before_it_has_travelled_far_enough():
    grid = open_map()
    origin = np.array([3.0, 10.0, 0.0])
    t = np.arange(12) * DT
    walker = np.stack([np.full_like(t, 6.0), 9.0 + 0.3 * t], axis=1)[:, None, :]
    reports = run(ScanTracker(grid), grid, origin, walker)
    # 0.3 m/s: min_travel (0.25 m) takes 0.8 s; the velocity is usable before
    early = next(k for k, r in enumerate(reports) if len(r.tentative))
    assert len(reports[early].ids) == 0 and early * DT < 0.8
    x, y, vx, vy, radius = reports[early].tentative[0]
    assert math.hypot(x - walker[early, 0, 0], y - walker[early, 0, 1]) < 0.15
    assert vy > 0.1 and radius > 0.1
    moving = next(k for k, r in enumerate(reports) if len(r.ids))
    assert moving > early and len(reports[moving].tentative) == 0


def test_static_unknown_obstacles_are_not_tentative_movers_for_long():
    grid = open_map()
    circles = [Circle((8.0, 8.5), 0.3), Circle((9.0, 12.0), 0.25), Circle((12.0, 10.0), 0.4)]
    tracker = ScanTracker(grid)
    tentative = []
    for k in range(80):
        origin = np.array([2.0 + 0.1 * k, 10.0, 0.0])
        world = World(grid, RobotSpec(radius=0.1), origin, unknown_obstacles=circles,
                      scan_config=ScanConfig(beams=BEAMS, range_max=12.0))
        tracker.update(ANGLES, world.scan().ranges, origin, k * DT)
        tentative.append(len(tracker.report().tentative))
    # once the hit ages show the returns stay put (static_age, 1 s), nothing is tentative
    assert sum(tentative[20:]) == 0


def test_a_box_whose_track_is_lost_while_the_robot_drives_round_it_is_not_reborn_moving():
    # a 0.37 m x 0.77 m box seen from a laser that drives round its corner at
    # 0.75 m/s (a traced run): its candidate grows past max_object_radius for
    # a while, the track dies, and the changing view then shifts the centre
    # of the new candidate by more than a metre per second
    grid = open_map()
    box = [Rectangle((4.57, 8.51), (4.94, 9.29))]
    corners = np.array([[8.5, 10.2], [6.58, 9.45], [5.66, 8.96], [5.17, 8.40], [5.0, 8.36]])
    legs = np.diff(corners, axis=0)
    ends = np.concatenate([[0.0], np.cumsum(np.hypot(*legs.T))])
    tracker = ScanTracker(grid)
    for k, walked in enumerate(np.arange(0.0, ends[-1], 0.075)):
        leg = min(np.searchsorted(ends, walked, side='right') - 1, len(legs) - 1)
        position = corners[leg] + (walked - ends[leg]) / (ends[leg + 1] - ends[leg]) * legs[leg]
        origin = np.array([*position, math.atan2(legs[leg, 1], legs[leg, 0])])
        world = World(grid, RobotSpec(radius=0.1), origin, unknown_obstacles=box,
                      scan_config=ScanConfig(beams=BEAMS, range_max=12.0))
        assert tracker.update(ANGLES, world.scan().ranges, origin, k * DT).accepted
        assert len(tracker.report().ids) == 0, (k, tracker.report().states)


def test_the_track_cap_bounds_the_live_tracks():
    grid = open_map()
    posts = [Circle((3.0 + 1.5 * k, 10.0 + (-1) ** k * 0.8), 0.25) for k in range(5)]
    tracker = ScanTracker(grid, TrackerParams(max_tracks=2))
    origin = np.array([2.0, 10.0, 0.0])
    world = World(grid, RobotSpec(radius=0.1), origin, unknown_obstacles=posts,
                  scan_config=ScanConfig(beams=BEAMS, range_max=12.0))
    for k in range(15):     # the posts' returns come to stay put while the tracks live
        assert tracker.update(ANGLES, world.scan().ranges, origin, k * DT).accepted
        assert tracker.live_tracks == 2
    assert len(tracker.report().ids) == 0


def test_a_walker_turning_round_stays_reported():
    grid = open_map()
    origin = np.array([3.0, 10.0, 0.0])
    t = np.arange(40) * DT
    # walks up at 0.4 m/s for 2 s, then back down: its speed passes through zero
    y = np.where(t < 2.0, 8.0 + 0.4 * t, 8.8 - 0.4 * (t - 2.0))
    walker = np.stack([np.full_like(t, 7.0), y], axis=1)[:, None, :]
    reports = run(ScanTracker(grid), grid, origin, walker)
    first = next(k for k, r in enumerate(reports) if len(r.ids))
    assert first * DT < 2.0
    assert all(len(r.ids) == 1 for r in reports[first:]), [len(r.ids) for r in reports]
    assert reports[-1].states[0, 3] < -0.2


def test_a_walker_stepping_out_from_behind_a_corner_stays_reported():
    # a block (x < 7.1 m, 3.4 m < y < 3.7 m) hides a person walking east along
    # its top face from a laser driving north past its end; while the person
    # comes out, the map explains its lower returns and the corner hides its
    # back, so its centre estimate stands still or slips back and its speed
    # estimate dips through zero before the visible part moves on
    grid = open_map(pillar=(slice(34, 37), slice(0, 71)))
    tracker = ScanTracker(grid)
    reported = []
    for k in range(20):
        t = k * DT
        origin = np.array([7.5, 2.8 + 0.8 * t, 0.0])
        ranges = scan_of(grid, origin, [(6.45 + 0.31 * t, 4.07)], radius=0.28)
        tracker.update(ANGLES, ranges, origin, t)
        report = tracker.report()
        reported.append(np.vstack([report.tracked, report.tentative]))
    first = next(k for k, rows in enumerate(reported) if len(rows))
    assert first * DT < 1.2
    assert all(len(rows) == 1 for rows in reported[first:]), [len(r) for r in reported]
    assert reported[-1][0, 2] > 0.2


def test_a_walker_stepping_out_from_behind_a_wall_is_reported_before_seen_whole():
    """A block (x 6-8 m, y 10.5-14 m) hides a person walking south at x = 9 m from a
    standing laser; for 1 s only a growing part of them shows beside the block's returns.
    Started on those glimpses, their track is reported while they are still partly hidden,
    walking the right way, and ends on their true velocity."""
    grid = walled_map()
    origin = np.array([3.0, 10.0, 0.0])
    t = np.arange(60) * DT
    walker = np.stack([np.full_like(t, 9.0), 13.0 - 0.5 * t], axis=1)
    reports = run(ScanTracker(grid), grid, origin, walker[:, None, :])
    first = next(k for k, r in enumerate(reports) if len(r.ids) or len(r.tentative))
    segments = segments_of(grid, scan_of(grid, origin, [walker[first]]), origin)
    seen = np.hypot(*(segments.centers - walker[first]).T) < RADIUS
    assert seen.sum() == 1 and segments.behind_map[seen][0], first   # still partly hidden
    rows = np.vstack([reports[first].tracked, reports[first].tentative])
    assert rows[0, 3] < -0.1, rows
    final = np.vstack([reports[-1].tracked, reports[-1].tentative])
    assert len(final) == 1 and math.hypot(final[0, 2], final[0, 3] + 0.5) < 0.1, final


@pytest.mark.parametrize('circle', [((9.0, 11.2), 0.3), ((8.5, 10.9), 0.2),
                                    ((9.5, 11.5), 0.4), ((10.0, 12.0), 0.3)])
def test_a_static_object_coming_out_from_behind_a_wall_is_not_a_mover(circle):
    """The laser drives past the block of the test above, and the visible part of an unknown
    object behind it grows as a person's would. Its track, started on the first glimpses,
    never moves; like any static object whose centre estimate wanders as the view changes,
    it may be a tentative mover, for at most 1 s."""
    grid = walled_map()
    for speed in (0.6, 1.0):
        tracker = ScanTracker(grid)
        glimpses, tentative = 0, []
        for k in range(int(6.0 / speed / DT)):
            origin = np.array([3.0, 12.0 - speed * k * DT, 0.0])
            world = World(grid, RobotSpec(radius=0.1), origin,
                          unknown_obstacles=[Circle(*circle)],
                          scan_config=ScanConfig(beams=BEAMS, range_max=12.0))
            ranges = world.scan().ranges
            segments = segments_of(grid, ranges, origin)
            glimpses += bool(np.any(segments.behind_map & (segments.radii >= 0.1)))
            assert tracker.update(ANGLES, ranges, origin, k * DT).accepted
            report = tracker.report()
            assert len(report.ids) == 0, (speed, k, report.states)
            if len(report.tentative):
                tentative.append(k * DT)
        assert glimpses > 0, speed             # the wall did hide part of it for a while
        assert not tentative or tentative[-1] - tentative[0] <= 1.0, (speed, tentative)


def test_only_a_wall_return_beside_a_candidate_puts_it_behind_the_map():
    """Behind the map: hidden by a return the map explains, not by an unknown object nor by
    the edge of a partial view."""
    origin = np.array([3.0, 10.0, 0.0])
    person = [(9.0, 10.7)]

    def candidate(grid, ranges, angles=ANGLES):
        segments = segments_of(grid, ranges, origin, angles)
        seen = np.hypot(*(segments.centers - person[0]).T) < 0.5
        assert seen.sum() == 1
        return bool(segments.occluded[seen][0]), bool(segments.behind_map[seen][0])

    walled = walled_map()                         # the block hides their upper part
    assert candidate(walled, scan_of(walled, origin, person)) == (True, True)
    # in the open: partly hidden by a box (not on the map), or by the edge of the view
    grid = open_map()
    box = ray_circle_distances(origin[:2], DIRECTIONS, np.array([[6.94, 10.69]]),
                               np.array([0.14]))
    assert candidate(grid, np.minimum(scan_of(grid, origin, person), box)) == (True, False)
    view = ANGLES <= 0.13
    assert candidate(grid, scan_of(grid, origin, person)[view], ANGLES[view]) == (True, False)
    assert candidate(grid, scan_of(grid, origin, person)) == (False, False)


def test_walkers_who_part_do_not_swing_a_track_the_wrong_way():
    grid = open_map()
    origin = np.array([3.0, 10.0, 0.0])
    t = np.arange(40) * DT
    # side by side (touching) up to 1.5 s, then one turns off to the right (+x)
    left = np.stack([np.full_like(t, 8.0), 8.0 + 0.6 * t], axis=1)
    right_x = np.where(t < 1.5, 8.6, 8.6 + 0.8 * (t - 1.5))
    right = np.stack([right_x, 8.0 + 0.6 * np.minimum(t, 1.5)], axis=1)
    reports = run(ScanTracker(grid), grid, origin, np.stack([left, right], axis=1))
    for k, report in enumerate(reports[16:], start=16):
        for (x, y, vx, vy) in report.states:
            # every reported velocity is one of the two walkers', never a swing between them
            near_left = math.hypot(x - left[k, 0], y - left[k, 1]) < 0.3
            truth = (0.0, 0.6) if near_left else (0.8, 0.0)
            assert math.hypot(vx - truth[0], vy - truth[1]) < 0.5, (k, report.states)


def test_two_walkers_side_by_side_are_two_tracks():
    grid = open_map()
    origin = np.array([3.0, 10.0, 0.0])
    t = np.arange(30) * DT
    # shoulder to shoulder (touching), walking at the laser
    x = 9.0 - 0.5 * t
    pair = np.stack([np.stack([x, np.full_like(t, 9.7)], axis=1),
                     np.stack([x, np.full_like(t, 10.3)], axis=1)], axis=1)
    reports = run(ScanTracker(grid), grid, origin, pair)
    final = reports[-1]
    assert len(final.ids) == 2
    for (px, py, vx, vy), radius in zip(final.states, final.radii):
        assert min(abs(py - 9.7), abs(py - 10.3)) < 0.15
        assert math.hypot(vx + 0.5, vy) < 0.2
        assert radius < 0.45


def test_two_walkers_who_fall_in_side_by_side_nearly_in_line_keep_their_tracks():
    """Seen from the laser one is partly behind the other: one run without a notch.

    The geometry of `crossing-2636032383`, where both tracks died and the robot drove
    into the pair: the run is wider than any object, so unless the tracks cut it apart
    it is static structure.
    """
    grid = open_map()
    origin = np.array([5.0, 10.0, 0.0])
    t = np.arange(30) * DT
    near = np.stack([np.full_like(t, 5.82), 7.9 + 0.48 * t], axis=1)
    # the farther one closes in from the side, then walks beside the nearer
    far = np.stack([6.43 + 0.3 * np.maximum(0.0, 1.2 - t), 8.02 + 0.48 * t], axis=1)
    reports = run(ScanTracker(grid), grid, origin, np.stack([near, far], axis=1))
    ids = reports[8].ids.tolist()
    assert len(ids) == 2
    for k, report in enumerate(reports[8:], start=8):
        assert report.ids.tolist() == ids, k
        for walker in (near[k], far[k]):
            gaps = np.hypot(*(report.states[:, 0:2] - walker).T)
            assert gaps.min() < 0.1, (k, report.states)
    for (x, y, vx, vy) in reports[-1].states:
        assert math.hypot(vx, vy - 0.48) < 0.15


def test_a_fast_walker_who_comes_out_from_behind_a_slow_one_leaves_both_tracks():
    """The two make one run without a notch (the nearer one's edge, then the farther one).

    The geometry of `fast-obstacle-3250530926`: the run, 1.3-1.9 times the size of either
    track, was taken by the nearer track (within the size gate) or was a new object, and the
    slow walker's track was lost for 1.5 s; the robot drove at them when they parted.
    """
    grid = open_map()
    origin = np.array([5.0, 3.9, 0.0])
    t = np.arange(45) * DT
    slow = np.stack([np.full_like(t, 5.76), 5.5 - 0.35 * t], axis=1)
    fast = np.stack([7.5 - 0.8 * t, np.full_like(t, 4.93)], axis=1)
    walkers = np.stack([slow, fast], axis=1)
    reports = run(ScanTracker(grid), grid, origin, walkers, radius=np.array([0.24, 0.32]))
    ids = sorted(reports[8].ids.tolist())
    assert len(ids) == 2
    for k, report in enumerate(reports[8:], start=8):
        assert sorted(report.ids.tolist()) == ids, k
        for walker in walkers[k]:
            assert np.hypot(*(report.states[:, 0:2] - walker).T).min() < 0.2, (k, report.states)
    for walker, velocity in ((slow[-1], (0.0, -0.35)), (fast[-1], (-0.8, 0.0))):
        state = reports[-1].states[np.argmin(np.hypot(*(reports[-1].states[:, 0:2] - walker).T))]
        assert math.hypot(state[2] - velocity[0], state[3] - velocity[1]) < 0.15


def test_a_walker_partly_hidden_behind_another_is_tracked_while_still_hidden():
    """One walks at the laser with part of them behind a nearer walker the whole time.

    The geometry of `crowd-1919764428`, where a person walking behind another was never
    tracked while partly hidden (3 s) and walked into the robot 0.7 s after coming out.
    """
    grid = open_map()
    origin = np.array([3.0, 10.0, 0.0])
    t = np.arange(40) * DT
    nearer = np.stack([6.0 - 0.3 * t, np.full_like(t, 10.0)], axis=1)
    hidden = np.stack([10.0 - 0.6 * t, np.full_like(t, 10.84)], axis=1)
    reports = run(ScanTracker(grid), grid, origin, np.stack([nearer, hidden], axis=1))
    for k in range(len(t)):
        segments = segments_of(grid, scan_of(grid, origin, [nearer[k], hidden[k]]), origin)
        seen = np.hypot(*(segments.centers - hidden[k]).T) < RADIUS
        assert seen.sum() == 1 and segments.occluded[seen][0], k     # partly hidden throughout
    first = next(k for k, r in enumerate(reports)
                 if len(r.ids) and np.hypot(*(r.states[:, 0:2] - hidden[k]).T).min() < 0.25)
    assert first * DT <= 2.0
    for k, report in enumerate(reports[first:], start=first):
        state = report.states[np.argmin(np.hypot(*(report.states[:, 0:2] - hidden[k]).T))]
        assert math.hypot(*(state[0:2] - hidden[k])) < 0.25
        assert math.hypot(state[2] + 0.6, state[3]) < 0.2, (k, state)


@pytest.mark.parametrize('box', [(10.0, 10.84), (8.0, 10.6), (6.8, 10.5)])
def test_a_static_box_coming_out_from_behind_a_walker_is_not_a_mover(box):
    """As a walker crossing in front uncovers a box, the visible part of the box grows and its
    centre estimate moves by up to its radius: a track started on it while partly hidden
    must not take that for walking (nor, once it is seen whole and larger, be lost and leave a
    ghost coasting at the speed the uncovering gave it)."""
    grid = open_map()
    origin = np.array([3.0, 10.0, 0.0])
    t = np.arange(40) * DT
    for start in (9.6, 10.0, 10.2):
        for speed in (0.3, 0.8, 1.2):
            walker = np.stack([np.full_like(t, 6.0), start + speed * t], axis=1)
            tracker = ScanTracker(grid)
            for k in range(len(t)):
                world = World(grid, RobotSpec(radius=0.1), origin,
                              unknown_obstacles=[Circle(box, 0.3)],
                              scan_config=ScanConfig(beams=BEAMS, range_max=12.0))
                ranges = np.minimum(world.scan().ranges, ray_circle_distances(
                    origin[:2], DIRECTIONS, walker[k:k + 1], np.array([RADIUS])))
                assert tracker.update(ANGLES, ranges, origin, k * DT).accepted
                report = tracker.report()
                assert np.all(np.hypot(*(report.states[:, 0:2] - box).T) > 0.6), (start, speed, k)


def test_range_noise_does_not_cut_a_walker_in_two():
    grid = open_map()
    explained = map_explained_mask(grid, TrackerParams().map_tolerance)
    origin = np.array([3.0, 10.0, 0.0])
    clean = scan_of(grid, origin, [[4.5, 10.0]])               # 1.5 m ahead: many beams
    noise = np.random.default_rng(7).normal(0.0, 0.02, size=(500, BEAMS))   # twice the simulated noise
    p = TrackerParams()
    counts = [len(segment_scan(ANGLES, clean + n, origin, grid, explained, p.cluster_gap,
                               p.min_points, p.split_depth).centers) for n in noise]
    assert counts == [1] * len(noise)


def test_a_walker_going_straight_is_seen_to_turn_less_than_one_who_wanders():
    """The heading diffusion starts at the prior, falls for a straight walk, rises for a wavy one."""
    grid = open_map()
    origin = np.array([3.0, 10.0, 0.0])
    t = np.arange(100) * DT                                       # 10 s
    straight = np.stack([6.0 + 0.5 * t, np.full_like(t, 7.0)], axis=1)
    heading = 1.2 * np.sin(2.0 * np.pi * t / 4.0)                 # swings +-70 degrees
    wavy = np.stack([6.0 + np.cumsum(0.5 * DT * np.cos(heading)),
                     13.0 + np.cumsum(0.5 * DT * np.sin(heading))], axis=1)
    reports = run(ScanTracker(grid), grid, origin, np.stack([straight, wavy], axis=1))
    prior = TrackerParams().turn_prior
    first = next(r for r in reports if len(r.ids) == 2)
    assert first.turn_stds.tolist() == [prior, prior]
    last = reports[-1]
    assert len(last.ids) == 2
    by_y = np.argsort(last.states[:, 1])
    straight_std, wavy_std = last.turn_stds[by_y]
    assert straight_std < 0.5 * prior < wavy_std
