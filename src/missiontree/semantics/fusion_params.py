"""How :class:`~missiontree.semantics.fusion.InstanceFusion` turns detections into instances: its parameters.

The fusion's settings, apart from its logic: the builder, the ``BuildSceneGraph`` leaf and the
benchmarks set them, and the fusion's helpers (:mod:`.absence`, :mod:`.merge`) read them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from missiontree.perception.tracking import NaisFilterParams


@dataclass(frozen=True)
class FusionParams:
    """How detections become instances and instances follow the world.

    Attributes:
        filters: The NAIS single-frame filters and voting (confidence 0.7, dynamic classes,
            4.5 m, 10 frames).
        associate_radius: A projection refines an instance of its label this close, metres.
        memory: Observations averaged into an instance's position (older ones fade).
        miss_frames: Frames that should show an instance and do not before it is removed.
        expect_range: An instance is expected in a frame (a frame without it counts as a miss) only
            this close to the camera, and within the range filter (``filters.max_range``), metres.
            Kept at the NAIS paper's 4.5 m when the range filter accepts farther detections: a
            far small object is often missed by the detector while it is there, and those misses
            would remove it.
        min_pixels: An instance is only expected in a frame where it would be at least this many
            pixels wide or high (and a third of it the other way: a bottle is narrow).
        edge_margin: Share of the image width kept clear at each side when judging visibility.
        depth_tolerance: Depth nearer than the instance's near surface by more than this means
            something stands in front of it, metres.
        miss_decay: Confidence kept after a miss.
        hit_gain: Share of the remaining doubt removed by an observation.
        move_window: Seconds within which an instance seen empty may be moved to a new sighting.
        min_elevation: A box whose centre's depth point lies lower than this above the floor shows
            the floor, not an object standing on it (tiles taken for a laptop), metres.
        floor_height: A depth pixel whose point lies lower than this shows the floor; where the
            instance's place shows floor at or past its near side, the camera sees through its place
            (a removed object's place seen from close by shows the floor just behind it), metres.
        present_miss_frames: Frames that should show an instance, whose depth shows *something* at
            its place, yet with no detection of its label, before it is removed (what stands there
            now is not it: an object taken off a desk leaves the desk).
        present_range: Only frames closer than this count towards ``present_miss_frames`` (farther,
            a small object is often missed by the detector while it is there), metres.
        present_min_pixels: Nor do frames where the instance would be smaller than this on the image
            (its larger side, pixels): the shipped detector finds a cup or a bottle in every frame
            from about 24 pixels and in none below 14, so a smaller view that misses it says nothing.
        place_margin: The depth patch judged at an instance's place is this much wider on each side
            than the instance (its position is an estimate), metres.
        edge_clip: A box within this many pixels of the image's left or right border is cut by it:
            its centre is not the object's, so it places nothing while uncut views exist (it still
            counts as an observation), pixels.
        candidate_memory: Seconds a candidate waits for its next sighting before it is forgotten
            (the paper's voting forgets within ``filters.candidate_timeout``; here the frames of
            several visits add up, so an object seen a few frames at a time from several places
            is confirmed).
        large_size: An instance or a box at least this wide (metres) is large: a box of its label
            whose inner part holds the instance's centre at a consistent depth refines it (views
            of a sofa from two sides place their near faces a metre apart), two instances one box
            holds are merged, and its centre comes from the outline of its surface points.
        inner_share: Share of a box's width at each side that is not its inner part.
        surface_cell: Cell size of the surface points kept per large instance, metres.
        min_uncut: Projections whose box no left, right or bottom image border cuts that a
            candidate needs before it is confirmed (a wall cut by the image's corners looks like a
            refrigerator; an object is seen with its foot and both sides in view a few times; the
            top may cut a tall one seen from close).
        min_uncut_share: Least share of a candidate's recent projections that must be whole.
        whole_size: A candidate this large (the larger of its boxes' median width and height at
            their depth, metres) is confirmed only once a box of it is cut by no image border, the
            top included: a wall seen from close fills the view like a refrigerator, and every box
            of such a phantom is cut by the image's top; a real tall object is seen whole from a
            few metres. None turns the rule off.
        small_size: A candidate whose boxes measure at most this much (larger side, median,
            metres) is small: the detector finds a bottle or a cup in a few frames of each visit.
        small_min_frames: Frames a small candidate needs instead of ``filters.min_frames``.
        size_margin: A candidate measured smaller than this share of its class's least size
            (:data:`~missiontree.perception.footprint.SIZE_PRIORS`) is not confirmed; 0 turns the check off.
        edge_band: Pixels beside a box whose depth is compared with the box's own at its sides.
        edge_step: Depth step (metres) at a box's side that shows an object standing out.
        min_bounded_share: Least share of a candidate's views in which it stands out in depth at an
            uncut side (a wall boxed as a refrigerator never does); 0 turns the check off.
        runner_up_share: An instance's label is reconsidered from its class evidence (each box's
            score for every class, summed over the views that refined it): when the footprint its
            surface points outline (several views) or its height is implausible for the class the
            detector names (:func:`~missiontree.perception.footprint.size_likelihood`: a 0.35 m deep
            "backpack"), the runner-up classes whose summed score reaches this share of the named
            class's are weighed, each by its score times how likely it is at the measured size,
            and the best that fits takes over (the instance is relabelled; boxes of the old label
            keep refining it). Only instances smaller than ``large_size`` are judged: the surface cells
            a large one gathers include what stands beside it (a tv against a cabinet measured 1 m
            deep). The share is low on purpose: the rule only acts once the named class is ruled
            out by size, and the detector's per-class floor (0.01 a box, against ~0.85 for the
            named class) makes a class that beats it in a third of the views reach 0.3 %.
            0 turns relabelling off.
        relabel_views: Views of an instance (observations) before its label is reconsidered.
        footprint_reach: Surface cells count towards a small instance's footprint within half its
            largest measured width plus this of its position, metres (farther ones are what stands
            beside it: a backpack against a cabinet measured 0.39 m deep with 0.3 m, 0.2 m with 0.1 m).
        explained_margin: A large instance's outline leaves out the surface cells within half the
            largest measured width plus this of another instance's centre that is smaller and not
            large itself (narrower than ``large_size``): its box's nearest surface was that object
            (a laptop on the floor before a table pulled the table's centre 0.6 m forward). A large
            one is not left out: it may be this object under another name (a tv also boxed as a
            table), and its own outline is no surer, metres; None turns the rule off.
        outline_margin: A large instance's outline is only used when its rectangle, grown by this,
            holds the fused position (the median of the boxes' centre points, which projection puts
            at most its ``max_surface_offset``, 0.45 m, behind the surface seen); else the cells
            outline a neighbour and the fused position stays, metres; None: not checked.
        twin_size: Two instances of different labels both at most this wide (metres) are small:
            one object when their footprints overlap (see ``twin_overlap``).
        twin_overlap: Two small instances of different labels at overlapping heights whose centres
            lie within this share of the sum of their half widths are one object the detector named
            two ways (two real objects at most touch: a share of 1; a bottle box on a cup came 4 cm
            from the 9 cm cup's centre); the one with less score mass for its label is removed.
            0 keeps only the general rule (a quarter of the smaller width).
        front_share: An instance is an object of its label seen on something in front of it (a box
            round a chair seen past a door frame, its centre's depth on the frame) when at least
            this share of the views that refined it held, inside the box's inner part and at least
            ``front_gap`` behind its measured depth, one instance of its label seen more often
            that the frame did not refine; it is removed, and later boxes of the label at its place
            that hold that instance again are dropped. 0 turns the rule off.
        front_fit: A box holds the instance behind only when it is at most this many times as wide
            as that instance would show at its distance (its median measured width): a box round the
            object behind is its size there, while a nearer object of the same class, a second desk
            in a row, shows wider (two desks 1 and 2.3 m away: 2.3 times); None: not checked.
        front_views: Views an instance is judged in before ``front_share`` applies.
        front_gap: How far behind a box's measured depth the other instance's centre lies, metres.
        small_radius: A projection at most ``small_width`` wide joins a candidate, or refines an
            instance at most that wide, of its label only this close instead of ``associate_radius``
            (two bottles of a set stand 0.5-0.9 m apart, and a small object's projections fall within
            centimetres of it: with 0.5 m one bottle's views fed the other's place and the second
            was never confirmed), metres; None turns the rule off.
        small_width: Width (metres) up to which a projection or an instance counts for ``small_radius``
            (a cup, a bottle, an umbrella; a backpack's centre depth scatters more).
        view_spread: A candidate whose uncut boxes were taken from camera places at least this far
            apart, and that all placed it in one spot (see ``view_agree``), needs only
            ``view_share`` of its frames: two places agreeing in depth is evidence a run of frames
            from one place is not (a plant seen 7 times from three places 3.4 m away, a cup 4 times
            from two, were left candidates); None turns the rule off, metres.
        view_agree: Most median distance of such a candidate's uncut placements from their
            median, or a quarter of its median measured width if larger, metres.
        view_share: Share of the frames otherwise needed that such a candidate needs.
        view_min_frames: Fewest frames it needs all the same.
        apart_share: Two instances of a label one box holds are two objects side by side (a box
            round both), not one, when both measure less than ``large_size`` wide (median of their
            boxes) and their centres lie farther apart than this share of their median widths
            summed (two 0.45 m plants 0.8 m apart were merged into one between them); None
            turns the rule off.
        cut_share: Two large instances of a label whose footprints overlap (centres closer than
            their half widths summed) are one object when at least this share of the less often
            seen one's placements came from boxes the image's left or right border cut (their
            centres are not the object's); None turns the rule off.
    """

    filters: NaisFilterParams = field(default_factory=NaisFilterParams)
    associate_radius: float = 0.5
    memory: int = 30
    miss_frames: int = 6
    expect_range: float = 4.5
    min_pixels: float = 14.0
    edge_margin: float = 0.06
    depth_tolerance: float = 0.35
    miss_decay: float = 0.7
    hit_gain: float = 0.3
    move_window: float = 600.0
    min_elevation: float = 0.03
    floor_height: float = 0.04
    present_miss_frames: int = 30
    present_range: float = 2.5
    present_min_pixels: float = 24.0
    place_margin: float = 0.05
    edge_clip: float = 2.0
    candidate_memory: float = 300.0
    large_size: float = 0.6
    inner_share: float = 0.2
    surface_cell: float = 0.05
    min_uncut: int = 3
    min_uncut_share: float = 0.2
    whole_size: float | None = 0.6
    small_size: float = 0.3
    small_min_frames: int = 5
    size_margin: float = 0.7
    edge_band: int = 6
    edge_step: float = 0.15
    min_bounded_share: float = 0.2
    runner_up_share: float = 0.003
    relabel_views: int = 10
    footprint_reach: float = 0.15
    explained_margin: float | None = 0.05
    outline_margin: float | None = 0.45
    twin_size: float = 0.45
    twin_overlap: float = 0.5
    front_share: float = 0.8
    front_views: int = 5
    front_fit: float | None = 1.4
    front_gap: float = 0.5
    cut_share: float | None = 0.5
    small_radius: float | None = 0.3
    small_width: float = 0.2
    view_spread: float | None = 0.5
    view_agree: float = 0.1
    view_share: float = 0.5
    view_min_frames: int = 3
    apart_share: float | None = 0.5
