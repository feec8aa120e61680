"""rigd.calibration.advice: next steps follow the assessment's numbers; each is a record of its words, the actions
it asks for (the CLI and the page say how), its axes and the pairs a capture needs in all."""

from dataclasses import replace

import numpy as np

from calib.assess import Assessment, Restart, Status, TrustOptions, Uncertainty, Verdict
from rigd.calibration.advice import Action, SceneFacts, next_steps

TRUST = TrustOptions()  # 0.2 deg / 2 cm, 2.5 sigma
FAR = SceneFacts(pairs=12, typical_range_m=16.0, pixels_per_radian=1000.0, translation_prior=False)


def assessment(sigma, status, weak, restarts=(), is_minimum=True, moved_deg=None, held_by=(), moved_m=None):
    sigma = np.asarray(sigma, dtype=float)
    unc = Uncertainty(np.eye(6), sigma, sigma, None, 0, "", is_minimum, 1.0, 0.9, held_by)
    return Assessment(np.zeros(6), None, unc, tuple(restarts), Verdict(status, tuple(weak), ("r",)), moved_deg,
                      moved_m)


def advise(a, facts, trust):
    """The steps' words."""
    return tuple(step.text for step in next_steps(a, facts, trust))


def test_trusted_needs_nothing():
    assert advise(assessment([0.01] * 3 + [0.3] * 3, Status.TRUSTED, ()), FAR, TRUST) == ()


def test_far_scene_with_weak_translation_suggests_near_structure_or_a_lever_arm_prior():
    steps = advise(assessment([0.02] * 3 + [0.5, 3.0, 0.5], Status.WEAK, ("y",)), FAR, TRUST)
    first = steps[0]
    assert first.startswith("y: translation is seen only through parallax") and "(16 m)" in first
    assert "0.62 px" in first  # 1000 px/rad * 1 cm / 16 m
    assert "structure 2-10 m" in first and "lever arm" in first and "hold the translation" in first
    actions = next_steps(assessment([0.02] * 3 + [0.5, 3.0, 0.5], Status.WEAK, ("y",)), FAR, TRUST)[0].actions
    assert actions == (Action.CAPTURE, Action.LEVER_ARM, Action.FIX_TRANSLATION)
    near = advise(assessment([0.02] * 3 + [0.5, 3.0, 0.5], Status.WEAK, ("y",)),
                      FAR._replace(typical_range_m=4.0), TRUST)[0]
    assert "(4 m) 1 cm moves an edge 2.5 px" in near and "structure" not in near and "hold the translation" in near
    # sigma 3 cm at 2.5 sigma against 2 cm: (7.5 / 2)^2 * 12 = 168.75 pairs: more of the same will not do it
    assert any("would not do it (about 169 needed" in s for s in steps)
    with_prior = advise(assessment([0.02] * 3 + [0.5, 3.0, 0.5], Status.WEAK, ("y",)),
                            FAR._replace(translation_prior=True), TRUST)
    assert not any("parallax" in s or "y:" in s for s in with_prior)


def test_weak_rotation_asks_for_about_as_many_pairs_as_sigma_needs():
    # pitch 2.5 * 0.1 = 0.25 deg against 0.2: 12 * 1.25^2 = 18.75 -> 19 pairs
    steps = advise(assessment([0.05, 0.1, 0.05, 0.3, 0.3, 0.3], Status.WEAK, ("pitch",)), FAR, TRUST)
    assert steps == ("pitch: capture more pairs at new places and headings, about 19 places in all (sigma falls "
                     "roughly as 1/sqrt(places); now 12), and keep the rig still during each capture",)
    (step,) = next_steps(assessment([0.05, 0.1, 0.05, 0.3, 0.3, 0.3], Status.WEAK, ("pitch",)), FAR, TRUST)
    assert step.actions == (Action.CAPTURE,) and step.pairs == 19 and step.axes == ("pitch",)


def test_failed_with_a_tie_and_few_pairs_says_why_and_not_to_use_it():
    tie = Restart(np.array([1.0, 0, 0, 0, 0, 0]), 0.5, "search runner-up")
    few = FAR._replace(pairs=4)
    steps = advise(assessment([0.05] * 3 + [0.3] * 3, Status.FAILED, ("roll",), [tie], is_minimum=False),
                       few, TRUST)
    assert steps[0].startswith("the finest level did not end at a minimum")
    assert any("another pose fits these pairs as well (search runner-up)" in s for s in steps)
    assert any(s.startswith("only 4 pairs") for s in steps)
    assert steps[-1].startswith("do not use this result")
    # a restart that ends elsewhere but clearly higher is not a tie
    far_above = Restart(np.array([1.0, 0, 0, 0, 0, 0]), 20.0)
    steps = advise(assessment([0.05] * 3 + [0.3] * 3, Status.WEAK, ("roll",), [far_above]), FAR, TRUST)
    assert not any("another pose" in s for s in steps)


def test_most_restarts_at_other_minima_point_at_the_edges_and_one_stuck_restart_does_not():
    away = Restart(np.array([2.0, 0, 0, 0, 0, 0]), 15.0)  # 2 deg off at a clearly higher cost
    back = Restart(np.array([0.01, 0, 0, 0.1, 0, 0]), 0.2)
    sigma = [0.05] * 3 + [0.3] * 3
    rugged = advise(assessment(sigma, Status.FAILED, (), [away, away, back, away]), FAR, TRUST)
    assert any(s.startswith("restarts near the solution ended at other minima") for s in rugged)
    one = advise(assessment(sigma, Status.WEAK, ("roll",), [away, back, back, back]), FAR, TRUST)
    assert not any("other minima" in s for s in one)


def test_a_solve_that_ran_far_from_its_start_points_at_the_overlays_and_the_guess():
    sharp = [0.05] * 3 + [0.3] * 3
    steps = advise(assessment(sharp, Status.FAILED, ("yaw",), moved_deg=45.5), FAR, TRUST)
    assert steps[0].startswith("the solve ran 46 deg from its start") and "global search" in steps[0]
    assert steps[-1].startswith("do not use this result")
    near = advise(assessment(sharp, Status.FAILED, ("yaw",), moved_deg=3.0), FAR, TRUST)
    assert not any("ran" in s and "from its start" in s for s in near)


def test_a_pose_resting_on_a_few_places_asks_for_more_places_not_for_thousands_of_pairs():
    """Five real street places where two hold z and roll (the jackknife without either slid to the kernel's
    width: sigma 30 cm): more pairs of such places do pin it (all ten: trusted), so no 1/sqrt(pairs) count."""
    sigma = [1.19, 0.51, 0.097, 0.87, 2.9, 30.6]
    few = FAR._replace(pairs=5)
    steps = advise(assessment(sigma, Status.FAILED, ("roll", "pitch", "z"), held_by=(1, 4)), few, TRUST)
    held = [s for s in steps if "rests on" in s]
    assert len(held) == 1 and held[0].startswith("roll, pitch, z: the pose rests on pairs/0001 and pairs/0004:")
    assert "without any one of them" in held[0] and "new places" in held[0]
    assert not any("would not do it" in s or "needed" in s for s in steps)
    one = advise(assessment(sigma, Status.WEAK, ("z",), held_by=(3,)), few, TRUST)
    assert any("rests on pairs/0003: without it " in s for s in one)
    assert any("would not do it" in s for s in advise(assessment(sigma, Status.FAILED, ("z",)), few, TRUST))


def test_the_places_a_pose_rests_on_are_named_by_their_folders():
    """A dataset whose pairs were pruned (pairs/0003, 0004, 0006, 0008, 0009): the fifth is pairs/0009, and its
    overlays (numbered by position) are named with it."""
    sigma = [0.79, 0.69, 0.04, 1.73, 1.30, 11.8]
    pruned = FAR._replace(pairs=5, pair_names=tuple(f"pairs/{n:04d}" for n in (3, 4, 6, 8, 9)))
    steps = advise(assessment(sigma, Status.FAILED, ("z",), held_by=(4,)), pruned, TRUST)
    assert any("the pose rests on pairs/0009 (overlays/0004_*): without it " in s for s in steps)


def test_the_pairs_asked_for_are_one_target_that_does_not_move_below_the_measured_count():
    """4 pairs asked for "about 8 in all", then those 8 for "about 11": one target, 12 (rigd's measured count),
    the same in the count step and in the "only N pairs" step."""
    for pairs, pitch_sigma in ((4, 0.113), (8, 0.094)):  # 8 and 11 pairs by the 1/sqrt(pairs) estimate
        facts = FAR._replace(pairs=pairs)
        steps = advise(assessment([0.05, pitch_sigma, 0.05, 0.3, 0.3, 0.3], Status.WEAK, ("pitch",)), facts, TRUST)
        assert "about 12 places in all" in steps[0] and f"now {pairs})" in steps[0], steps
        assert steps[1].startswith(f"only {pairs} pairs: rigd is measured with 12 places")
        records = next_steps(assessment([0.05, pitch_sigma, 0.05, 0.3, 0.3, 0.3], Status.WEAK, ("pitch",)), facts,
                             TRUST)
        assert [s.pairs for s in records] == [12, 12]


def test_a_translation_that_ran_metres_points_at_the_lever_arms_unit():
    steps = advise(assessment([0.05] * 3 + [0.3] * 3, Status.FAILED, (), moved_m=19.1), FAR, TRUST)
    assert steps[0].startswith("the translation ran 19.1 m from its start") and "its unit" in steps[0]
    step = next_steps(assessment([0.05] * 3 + [0.3] * 3, Status.FAILED, (), moved_m=19.1), FAR, TRUST)[0]
    assert step.actions == (Action.LEVER_ARM,) and step.axes == ("x", "y", "z")


def test_an_axis_the_elevation_offset_sets_asks_for_a_better_known_offset_not_more_pairs():
    def with_elevation(z_part_cm):
        a = assessment([0.03, 0.03, 0.02, 0.3, 0.6, 1.2], Status.WEAK, ("z",))
        part = np.array([0.01, 0.01, 0.0, 0.03, 0.01, z_part_cm])
        return advise(replace(a, uncertainty=replace(a.uncertainty, elevation=part)),
                          FAR._replace(typical_range_m=4.0), TRUST)

    steps = with_elevation(1.1)  # of z's 1.2 cm, the offset's 1.1
    said = [s for s in steps if "elevation offset" in s]
    assert len(said) == 1 and said[0].startswith("z: the LiDAR's elevation offset is not known well enough")
    assert "moves z by 1.1 cm" in said[0] and "fit the offset" in said[0] and "declare it" in said[0]
    assert not any(s.startswith("z: capture more pairs") for s in steps)
    data_set = with_elevation(0.3)  # the data's own sigma sets z: more pairs, as before
    assert not any("elevation offset" in s for s in data_set)
    assert any(s.startswith("z: capture more pairs") for s in data_set)


def test_an_axis_the_methods_disagree_on_names_the_disagreement_not_more_pairs():
    a = assessment([0.03, 0.3, 0.02, 0.3, 0.3, 0.3], Status.WEAK, ("pitch",))
    part = np.array([0.0, 0.28, 0.0, 0.0, 0.0, 0.0])  # of pitch's 0.3 deg, the disagreement's 0.28
    steps = next_steps(replace(a, uncertainty=replace(a.uncertainty, cross_check=part)), FAR, TRUST)
    said = [s for s in steps if "disagree" in s.text]
    assert len(said) == 1 and said[0].axes == ("pitch",) and said[0].text.startswith("pitch: the image's edges")
    assert "move pitch by 0.4 deg" in said[0].text  # the move itself: its part is move / sqrt(2)
    assert not any(s.text.startswith("pitch: capture more pairs") for s in steps)


def test_pairs_at_one_place_count_once_and_the_capture_asks_for_new_places():
    """20 pairs at one place (the rig never moved): the advice counts the place, and the capture's target in all
    is the 20 pairs plus one at each of 11 new places."""
    one_place = FAR._replace(pairs=20, place_of=(0,) * 20)
    steps = next_steps(assessment([0.05, 0.1, 0.05, 0.3, 0.3, 0.3], Status.WEAK, ("pitch",)), one_place, TRUST)
    assert "now 20 pairs at 1 place" in steps[0].text
    assert steps[-1].text.startswith("only 20 pairs at 1 place: rigd is measured with 12 places")
    assert [s.pairs for s in steps] == [steps[0].pairs, 31] and steps[0].pairs >= 31


def test_a_lever_arm_the_data_disagree_with_asks_to_check_it_and_its_unit():
    """The verdict's evidence (calib.assess.Evidence): 18 sigma from the lever arm given, or held values that fit
    far worse than free: the first step asks to check the lever arm and its unit."""
    from calib.assess import Evidence

    a = assessment([0.05] * 3 + [0.3] * 3, Status.WEAK, ("x", "y", "z"))
    far = next_steps(replace(a, evidence=Evidence(prior_z=(0.5, 18.0))), FAR, TRUST)
    assert far[0].text.startswith("the translation lies 18 sigma from the lever arm given: check it and its unit")
    assert far[0].actions == (Action.LEVER_ARM,) and far[0].axes == ("x", "y", "z")
    held = next_steps(replace(a, evidence=Evidence(fixed=("x", "y", "z"), fixed_worse_nll=150.0)), FAR, TRUST)
    assert held[0].text.startswith("x, y, z held at the values given fit clearly worse than free")
    near = next_steps(replace(a, evidence=Evidence(prior_z=(0.5, 2.0))), FAR, TRUST)
    assert not any("sigma from the lever arm" in s.text for s in near)
