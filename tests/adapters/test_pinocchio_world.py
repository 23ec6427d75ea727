"""CollisionWorld against a brute-force pairwise reference, plus object bookkeeping."""

import time

import numpy as np
import pytest

pin = pytest.importorskip("pinocchio")
coal = pytest.importorskip("coal")

from interlayer_pinocchio import CollisionWorld, Robot  # noqa: E402


def translation(x, y, z):
    pose = np.eye(4)
    pose[:3, 3] = (x, y, z)
    return pose


@pytest.fixture(scope="module")
def robot():
    return Robot.load("pr2")


def table_world(robot, seed=0):
    """A table (fixed) with 15 cylinders on it (12 movable, 3 fixed), 1 mm above the top."""
    world = CollisionWorld(robot)
    world.add_box("table", (0.6, 1.2, 0.7), translation(0.8, 0.0, 0.35))
    rng = np.random.default_rng(seed)
    for i in range(15):
        radius, height = rng.uniform(0.02, 0.045), rng.uniform(0.1, 0.3)
        pose = translation(rng.uniform(0.55, 1.05), rng.uniform(-0.55, 0.55), 0.7 + height / 2 + 1e-3)
        world.add_cylinder(f"cyl{i}", radius, height, pose, movable=i % 5 != 0)
    return world


def holding_world(robot, seed=0):
    """table_world + a mug in the left hand and a block in the right hand."""
    world = table_world(robot, seed)
    q = robot.neutral_q()
    world.add_cylinder("mug", 0.03, 0.12, robot.tool_pose(q, "left"), movable=True)
    world.add_box("block", (0.04, 0.04, 0.16), robot.tool_pose(q, "right") @ translation(0.0, 0.0, 0.05),
                  movable=True)
    world.attach("mug", "left", q)
    world.attach("block", "right", q)
    return world


class Reference:
    """Ground truth: every pair checked one by one (pin.computeCollisions without broadphase).

    Built independently of CollisionWorld's masks: all pairs are computed, then the
    documented rules are applied in Python.  Held objects are re-placed each time
    from tool_pose(q) @ grasp.
    """

    def __init__(self, robot, world):
        self.robot, self.world = robot, world
        self.objects = {o.name: o for o in world.objects()}
        gm = pin.GeometryModel()
        for go in robot.collision_model.geometryObjects:
            gm.addGeometryObject(go)
        self.n_robot = gm.ngeoms
        self.labels = [robot.model.frames[go.parentFrame].name
                       for go in robot.collision_model.geometryObjects]
        for name, obj in self.objects.items():
            gm.addGeometryObject(pin.GeometryObject(name, 0, 0, pin.SE3(obj.pose), world.geometry(name)))
            self.labels.append(name)
        # self pairs: the SRDF-filtered list is the definition of what may self-collide
        pairs = [(p.first, p.second) for p in robot.collision_model.collisionPairs]
        pairs += [(a, b) for a in range(self.n_robot) for b in range(self.n_robot, gm.ngeoms)]
        pairs += [(a, b) for a in range(self.n_robot, gm.ngeoms) for b in range(a + 1, gm.ngeoms)]
        for a, b in pairs:
            gm.addCollisionPair(pin.CollisionPair(a, b))
        self.gm, self.gd, self.pairs = gm, pin.GeometryData(gm), pairs
        self.data = robot.model.createData()
        self.hands = {arm: set(robot.gripper_links(arm)) for arm in ("left", "right")}

    def raw(self, q):
        """All colliding (label_a, label_b) pairs, no filtering."""
        for name, obj in self.objects.items():
            if obj.held_by:
                pose = self.robot.tool_pose(q, obj.held_by) @ obj.grasp
                self.gm.geometryObjects[self.gm.getGeometryId(name)].placement = pin.SE3(pose)
        pin.computeCollisions(self.robot.model, self.data, self.gm, self.gd, q, False)
        return [(self.labels[a], self.labels[b], a, b) for k, (a, b) in enumerate(self.pairs)
                if self.gd.collisionResults[k].isCollision()]

    def counts(self, pair, ignore, movables):
        la, lb, a, b = pair
        if a < self.n_robot and b < self.n_robot:
            return True  # self-collision (SRDF-filtered)
        if la in ignore or lb in ignore:
            return False
        if a < self.n_robot:
            obj = self.objects[lb]
            if obj.held_by:
                return self.robot.collision_model.geometryObjects[a].name not in self.hands[obj.held_by]
            return movables or not obj.movable
        oa, ob = self.objects[la], self.objects[lb]
        if not (oa.held_by or ob.held_by):
            return False  # environment vs environment never counts
        other = ob if oa.held_by else oa
        return bool(other.held_by) or movables or not other.movable

    def in_collision(self, raw, ignore=frozenset(), movables=True):
        return any(self.counts(p, ignore, movables) for p in raw)

    def colliding_movables(self, raw, ignore=frozenset()):
        hits = set()
        for la, lb, a, b in raw:
            if b < self.n_robot or la in ignore or lb in ignore:
                continue
            sides = [(la, lb)] if a < self.n_robot else [(la, lb), (lb, la)]
            for toucher, target in sides:
                t = self.objects[target]
                if t.movable and not t.held_by and (toucher in self.labels[:self.n_robot]
                                                    or self.objects[toucher].held_by):
                    hits.add(target)
        return hits


def sample_near_table(robot, rng):
    q = robot.random_q(rng, groups=("left_arm", "right_arm", "left_gripper", "right_gripper"))
    return robot.set(q, "base", [rng.uniform(-0.4, 0.4), rng.uniform(-0.9, 0.9), rng.uniform(-np.pi, np.pi)])


@pytest.mark.parametrize("holding", [False, True], ids=["free-hands", "holding"])
def test_in_collision_matches_pairwise_ground_truth(robot, holding):
    world = (holding_world if holding else table_world)(robot)
    ref = Reference(robot, world)
    rng = np.random.default_rng(42 + holding)
    ignore = frozenset({"cyl3", "table"} | ({"mug"} if holding else set()))
    counts = dict(configs=0, colliding=0, relaxed_colliding=0, ignore_colliding=0, touching_movables=0,
                  held_pairs=0)
    for _ in range(1250):
        q = sample_near_table(robot, rng)
        raw = ref.raw(q)
        expected = ref.in_collision(raw)
        assert world.in_collision(q) is expected, (q, raw)
        relaxed = ref.in_collision(raw, movables=False)
        assert world.in_collision(q, movables=False) is relaxed
        ignored = ref.in_collision(raw, ignore=ignore)
        assert world.in_collision(q, ignore=ignore) is ignored
        movers = ref.colliding_movables(raw)
        assert world.colliding_movables(q) == movers
        assert world.colliding_movables(q, ignore={"cyl1"}) == ref.colliding_movables(raw, {"cyl1"})
        reported = {frozenset(p) for p in world.collision_pairs(q)}
        assert reported == {frozenset(p[:2]) for p in raw if ref.counts(p, frozenset(), True)}
        counts["configs"] += 1
        counts["colliding"] += expected
        counts["relaxed_colliding"] += relaxed
        counts["ignore_colliding"] += ignored
        counts["touching_movables"] += bool(movers)
        counts["held_pairs"] += any(ref.counts(p, frozenset(), True) and any(
            name in ref.objects and ref.objects[name].held_by for name in p[:2]) for p in raw)
    print(f"\nholding={holding}: {counts}")
    n = counts["configs"]
    assert 0.15 * n < counts["colliding"] < 0.85 * n
    assert counts["relaxed_colliding"] < counts["colliding"]
    assert counts["touching_movables"] > 0.05 * n
    if holding:
        assert counts["held_pairs"] > 0.05 * n


def test_a_configuration_clear_of_movables_is_answered_without_collecting_pairs(robot, monkeypatch):
    """colliding_movables asks the cheap yes/no check first; only a hit collects the colliding pairs."""
    world = table_world(robot)
    collected = []
    collect = world._colliding_pairs
    monkeypatch.setattr(world, "_colliding_pairs", lambda *a: collected.append(1) or collect(*a))
    assert world.colliding_movables(robot.default_q()) == set() and not collected  # tucked, far from the table
    q = robot.set(robot.default_q(base=(0.0, 0.0, 0.0)), "base", [0.7, 0.0, 0.0])  # driven into the table
    assert world.colliding_movables(q) and collected


@pytest.mark.parametrize("group", ["left_arm", "right_arm", "base"])
def test_group_checker_matches_ground_truth(robot, group):
    world = holding_world(robot, seed=3)
    ref = Reference(robot, world)
    rng = np.random.default_rng(7)
    # the fixed part must be collision-free: arms raised (arm groups) or folded in (base)
    if group == "base":
        left = [1.2, 1.0, 1.6, -2.0, 0.0, -0.5, 0.0]
    else:
        left = [0.5, -0.3, 0.0, -1.5, 0.0, -0.5, 0.0]
    mirrored = [-left[0], left[1], -left[2], left[3], -left[4], left[5], -left[6]]
    q_fixed = robot.set(robot.set(robot.neutral_q(), "left_arm", left), "right_arm", mirrored)
    assert not ref.in_collision(ref.raw(q_fixed))
    is_valid = world.checker_for(group, q_fixed)
    g = robot.group(group)
    colliding = 0
    for _ in range(500):
        values = g.sample(rng)
        if group == "base":
            values = [rng.uniform(-0.4, 0.6), rng.uniform(-1.0, 1.0), values[2]]
        expected = ref.in_collision(ref.raw(g.set(q_fixed, values)))
        got = is_valid(values)
        assert type(got) is bool
        assert got is (not expected), values
        assert world.in_collision(g.set(q_fixed, values), group=group) is expected
        colliding += expected
    print(f"\n{group}: {colliding}/500 colliding")
    assert 25 < colliding < 475


def test_checker_follows_world_changes(robot):
    world = CollisionWorld(robot)
    world.add_box("table", (0.6, 1.2, 0.7), translation(0.8, 0.0, 0.35))
    q = robot.default_q()
    is_valid = world.checker_for("base", q)
    assert is_valid([0.0, 0.0, 0.0]) and not is_valid([0.6, 0.0, 0.0])  # drives into the table
    world.set_pose("table", translation(3.0, 0.0, 0.35))
    assert is_valid([0.6, 0.0, 0.0])
    world.add_box("wall", (0.1, 2.0, 1.0), translation(0.0, 0.0, 0.5))
    assert not is_valid([0.0, 0.0, 0.0])
    world.remove("wall")
    assert is_valid([0.0, 0.0, 0.0])
    with pytest.raises(KeyError):
        world.checker_for("base", q, ignore={"no-such-object"})


def test_attach_detach_moves_object_with_gripper(robot):
    world = CollisionWorld(robot)
    q0 = robot.neutral_q()  # arms straight ahead, far from everything
    tool0 = robot.tool_pose(q0, "left")
    world.add_cylinder("mug", 0.03, 0.12, tool0, movable=True)
    assert world.in_collision(q0)  # the closed fingers cut into the mug
    assert world.colliding_movables(q0) == {"mug"}
    assert not world.in_collision(q0, ignore={"mug"})

    world.attach("mug", "left", q0)
    (held,) = world.held()
    assert (held.name, held.arm) == ("mug", "left")
    np.testing.assert_allclose(held.tool_T_object, np.eye(4), atol=1e-12)
    assert not world.in_collision(q0)  # the holding hand is excluded
    with pytest.raises(ValueError):
        world.pose("mug")
    with pytest.raises(ValueError):
        world.set_pose("mug", tool0)

    # an obstacle at the end of the mug (clear of the fingers) is hit by the mug only
    world.add_box("cube", (0.02, 0.02, 0.02), tool0 @ translation(0.0, 0.0, 0.055), movable=True)
    assert world.in_collision(q0)
    assert world.collision_pairs(q0) == [("mug", "cube")]
    assert world.colliding_movables(q0) == {"cube"}
    assert not world.in_collision(q0, ignore={"cube"})
    assert not world.in_collision(q0, movables=False)

    q1 = robot.set(q0, "left_arm", [0.6, 0.3, 0.0, -0.4, 1.0, -0.3, 0.5])
    tool1 = robot.tool_pose(q1, "left")
    np.testing.assert_allclose(world.pose("mug", q1), tool1, atol=1e-12)
    assert not world.in_collision(q1)
    assert world.objects_overlap("cube", world.pose("cube")) == set()  # held mug is not an obstacle here

    world.detach("mug", q1)
    assert world.held() == ()
    np.testing.assert_allclose(world.pose("mug"), tool1, atol=1e-12)
    assert world.get("mug").held_by is None
    assert world.in_collision(q1)  # the released mug is an obstacle for the (closed) fingers again
    hand_links = {name[:-2] for name in robot.gripper_links("left")}  # geometry "<link>_0" -> link
    assert {link for link, obj in world.collision_pairs(q1)} <= hand_links
    assert not world.in_collision(q1, ignore={"mug"})
    q2 = robot.set(q1, "left_arm", [0.0] * 7)
    assert not world.in_collision(q2)  # it stayed behind


def test_objects_overlap_and_listing(robot):
    world = table_world(robot)
    top = 0.7
    assert world.objects_overlap("cyl1", world.pose("cyl1")) <= {f"cyl{i}" for i in range(15)}
    r, h = world.get("cyl1").size
    assert world.get("table").size == (0.6, 1.2, 0.7)  # full edge lengths
    free_spot = translation(0.8, 0.0, top + h / 2 + 1e-3)
    hits = world.objects_overlap("cyl1", free_spot, ignore={f"cyl{i}" for i in range(15)})
    assert hits == set()
    sunk = translation(0.8, 0.0, top + h / 2 - 0.01)
    assert "table" in world.objects_overlap("cyl1", sunk)
    on_other = world.pose("cyl2")
    assert "cyl2" in world.objects_overlap("cyl1", on_other)
    names = [o.name for o in world.objects()]
    assert names[0] == "table" and len(names) == 16 and world.names() == tuple(names)
    assert world.get("cyl0").movable is False and world.get("cyl1").movable is True
    world.add_box("red", (0.1, 0.1, 0.1), translation(0.0, 2.0, 0.05), movable=True, color=(1, 0, 0, 1))
    red = world.get("red")
    assert (red.shape, red.size, red.color, red.held_by) == ("box", (0.1, 0.1, 0.1), (1, 0, 0, 1), None)
    assert world.get("cyl1").shape == "cylinder" and world.get("table").color == (0.7, 0.7, 0.7, 1.0)
    with pytest.raises(ValueError):
        world.set_pose("red", np.diag([2.0, 1.0, 1.0, 1.0]))  # not a rigid transform
    with pytest.raises(ValueError):
        world.add_box("table", (1, 1, 1), np.eye(4))
    with pytest.raises(KeyError):
        world.remove("nothing")


def test_mesh_objects(robot):
    world = CollisionWorld(robot)
    palm = robot.urdf_path.parent.parent / "meshes" / "gripper_v0" / "gripper_palm.stl"
    q = robot.default_q()
    world.add_mesh("thing", str(palm), translation(2.0, 0.0, 0.5), scale=(2.0, 2.0, 2.0))
    assert not world.in_collision(q)
    world.set_pose("thing", translation(0.0, 0.0, 0.3))
    assert world.in_collision(q)


def test_timing_report(robot):
    """Not a benchmark gate, just numbers in the log (-s): per-call costs on this machine."""
    world = table_world(robot)
    rng = np.random.default_rng(0)
    q = robot.default_q(base=(0.05, 0.0, 0.0))
    qs = [sample_near_table(robot, rng) for _ in range(2000)]
    t = time.perf_counter()
    for x in qs:
        world.in_collision(x)
    full = (time.perf_counter() - t) / len(qs)
    report = {"in_collision(random near table)": full}
    for group in ("left_arm", "base"):
        is_valid = world.checker_for(group, q)
        g = robot.group(group)
        values = [g.sample(rng) * ([0.3, 0.3, 1.0] if group == "base" else 1.0) for _ in range(2000)]
        t = time.perf_counter()
        for v in values:
            is_valid(v)
        report[f"checker_for({group})"] = (time.perf_counter() - t) / len(values)
    print("\n" + ", ".join(f"{k}: {v * 1e6:.1f} us" for k, v in report.items()))  # a report: no speed gate


def test_motion_bound_bounds_how_far_any_body_moves(robot):
    """No point of a robot link or held object moves further than motion_bound x the group-vector
    distance: single-joint moves of an outstretched arm, with and without a long stick in the hand,
    and base moves."""
    world = CollisionWorld(robot)
    q0 = robot.set(robot.neutral_q(), "left_arm", [0.3, 0.0, 0.0, -0.2, 0.0, -0.2, 0.0])  # stretched out

    def corners(q):  # corners of every moving geometry's local bounding box, in the world
        gm = world._gm
        gd = pin.GeometryData(gm)
        pin.updateGeometryPlacements(robot.model, robot.model.createData(), gm, gd, q)
        return np.array([gd.oMg[k].act(np.array([x, y, z])) for k, go in enumerate(gm.geometryObjects)
                         if go.parentJoint > 0 for box in [go.geometry.aabb_local]
                         for x in (box.min_[0], box.max_[0]) for y in (box.min_[1], box.max_[1])
                         for z in (box.min_[2], box.max_[2])])

    for stick in (False, True):
        if stick:
            world.add_box("stick", (2.5, 0.02, 0.02), robot.tool_pose(q0, "left") @ translation(1.2, 0, 0), movable=True)
            world.attach("stick", "left", q0)
        for group in ("left_arm", "base"):
            bound = world.motion_bound(group)
            g = robot.group(group)
            v0, worst = g.get(q0), 0.0
            for i in range(g.dof):
                dv = np.zeros(g.dof)
                dv[i] = 0.01
                worst = max(worst, np.linalg.norm(corners(g.set(q0, v0 + dv)) - corners(q0), axis=1).max() / 0.01)
            assert worst <= bound
            if group != "base":  # not a vacuous bound (the base's counts every link stretched out)
                assert worst > bound / np.sqrt(g.dof)


def test_an_arm_checker_leaves_out_what_the_arm_cannot_reach_and_follows_it_when_moved(robot):
    """An arm's checker keeps bodies beyond the arm's reach out of the broad phase (they cannot
    collide with it), and takes one back in when set_pose brings it within reach: same answers."""
    world = CollisionWorld(robot)
    world.add_box("table", (0.6, 1.2, 0.7), translation(0.8, 0.0, 0.35))
    world.add_box("far", (0.2, 0.2, 0.2), translation(4.0, 0.0, 0.8), movable=True)
    q = robot.default_q()
    g = robot.group("left_arm")
    reach = [0.3, 0.0, 0.0, -0.2, 0.0, -0.2, 0.0]  # stretched out in front
    is_valid = world.checker_for("left_arm", q)
    assert is_valid(reach) and not world.in_collision(g.set(q, reach))
    slot = next(s for s in world._slots if s.far is not None)  # the checker's
    assert slot.off[world._gm.getGeometryId("far")] and not slot.off[world._gm.getGeometryId("table")]
    world.set_pose("far", robot.tool_pose(g.set(q, reach), "left"))  # now where the hand is
    assert world.in_collision(g.set(q, reach)) and not is_valid(reach)
    world.set_pose("far", translation(4.0, 0.0, 0.8))
    assert is_valid(reach)


def test_the_broad_phase_meets_the_objects_before_the_robots_self_pairs(robot):
    """A check stops at its first hit, and the manager tests geometries in the order they were
    registered: the objects come first, so an arm in an object is found before the robot's self pairs
    (the costliest meshes) are tested, also after the slot changes which geometries it leaves out."""
    world = table_world(robot)
    q = robot.default_q()
    checks = [lambda: world.in_collision(q), lambda: world.checker_for("left_arm", q)([0.0] * 7),
              lambda: world.in_collision(q, movables=False)]
    # more query kinds than slots: a reused slot takes back the cylinder the last one ignored
    checks += [lambda i=i: world.in_collision(q, ignore={f"cyl{i}"}) for i in range(12)]
    for check in checks:
        check()
        slot = world._slots[0]
        objs = slot.manager.getManager().getObjects()
        registered = [objs[i].collisionGeometry() for i in range(len(objs))]
        assert len(registered) == int((~slot.off).sum())
        first_mesh = [isinstance(g, coal.BVHModelBase) for g in registered].index(True)  # the robot's links
        assert any(isinstance(g, coal.Cylinder) for g in registered[:first_mesh])
        assert not any(isinstance(g, coal.Cylinder) for g in registered[first_mesh:])  # no object after them


@pytest.mark.parametrize("name", ["pr2", "panda"])
def test_an_arms_reach_bounds_every_body_it_moves(name):
    """What an arm's checker leaves out rests on _reach: no corner of a body moving with the arm (its
    links, the fingers at any opening, a held object) gets further from the arm's first joint."""
    robot = Robot.load(name)
    world = CollisionWorld(robot)
    arm = robot.arms[0]
    q0 = robot.default_q()
    world.add_box("stick", (0.4, 0.02, 0.02), robot.tool_pose(q0, arm) @ translation(0.15, 0, 0), movable=True)
    world.attach("stick", arm, q0)
    world.in_collision(q0)  # builds the geometry model
    root, radius = world._reach(f"{arm}_arm")
    gm, gd, data = world._gm, pin.GeometryData(world._gm), robot.model.createData()
    rng = np.random.default_rng(1)
    worst = 0.0
    for _ in range(300):
        q = robot.random_q(rng, q0, groups=(f"{arm}_arm", f"{arm}_gripper"))
        pin.updateGeometryPlacements(robot.model, data, gm, gd, q)
        centre = data.oMi[root].translation
        for k, go in enumerate(gm.geometryObjects):
            if go.parentJoint > 0 and root in robot.model.supports[go.parentJoint]:
                box = go.geometry.aabb_local
                for corner in ((x, y, z) for x in (box.min_[0], box.max_[0]) for y in (box.min_[1], box.max_[1])
                               for z in (box.min_[2], box.max_[2])):
                    worst = max(worst, np.linalg.norm(gd.oMg[k].act(np.array(corner)) - centre))
    assert worst <= radius
    assert worst > 0.6 * radius  # not a vacuous bound


@pytest.mark.parametrize("holding", [False, True], ids=["free-hands", "holding"])
def test_a_groups_pairs_are_those_a_group_joint_lies_between(robot, holding):
    """A group's query keeps exactly the pairs whose two geometries (robot links by their joint, held
    objects by the holding wrist, the rest on the universe) have a group joint in one support and not the
    other: here from the model's supports, pair by pair, for every group."""
    world = (holding_world if holding else table_world)(robot)
    world.in_collision(robot.neutral_q())  # builds the geometry model
    supports, nr = robot.model.supports, world._n_robot
    joint = {g: int(world._robot_joint[g]) for g in range(nr)}
    for o in world.objects():
        gid = world._gm.getGeometryId(o.name)
        joint[gid] = world._tool_joint[o.held_by] if o.held_by else 0
    for group in robot.groups:
        ids = set(robot.group(group).joint_ids)
        moved = {g: frozenset(ids.intersection(supports[j])) if j else frozenset() for g, j in joint.items()}
        changes = np.array([moved[int(a)] != moved[int(b)] for a, b in zip(world._pa, world._pb)])
        for mode, ignore, movables in (("check", frozenset(), True), ("check", frozenset({"cyl3"}), False),
                                       ("movables", frozenset(), True)):
            whole = world._mask(mode, None, ignore, movables)
            assert (world._mask(mode, group, ignore, movables) == (whole & changes)).all(), (group, mode)
        assert changes.any() and not changes.all()


def test_a_slot_switched_between_query_kinds_activates_exactly_their_pairs(robot):
    """A slot going from one query kind to another flips the pairs that differ, one call each when they
    are few, the whole mask at once when they are many: either way its GeometryData ends with exactly
    the new kind's pairs active."""
    from interlayer_pinocchio.pairs import _Slot

    world = holding_world(robot)
    world.in_collision(robot.neutral_q())
    keys = [("check", None, frozenset(), True), ("movables", None, frozenset(), True),
            ("check", "left_arm", frozenset({"cyl3"}), False), ("check", "base", frozenset(), True),
            ("check", None, frozenset({"cyl1"}), True), ("check", "right_gripper", frozenset(), True)]
    slot = _Slot(world._model, world._gm, world._n_robot)
    rng = np.random.default_rng(3)
    flips = []
    for k in rng.integers(len(keys), size=40):
        v = world._variant(keys[k])
        flips.append(int((slot.mask != v.mask).sum()))
        slot.apply(v, None)
        assert list(slot.gd.activeCollisionPairs) == v.mask.tolist(), keys[k]
    third = len(slot.mask) // 3
    assert any(0 < f <= third for f in flips) and any(f > third for f in flips)  # both ways taken
