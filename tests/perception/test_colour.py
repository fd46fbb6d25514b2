from __future__ import annotations

import numpy as np
import pytest

from missiontree.perception.colour import (
    COLOUR_NAMES,
    canonical_colour,
    colour_classes,
    colour_mask,
    dominant_colour,
    find_colour,
    horizontal_position,
)

SWATCHES = {
    "red": (200, 30, 30),
    "orange": (240, 140, 20),
    "brown": (120, 70, 30),
    "yellow": (230, 220, 40),
    "green": (40, 170, 60),
    "cyan": (30, 200, 210),
    "blue": (40, 60, 200),
    "purple": (120, 40, 180),
    "pink": (230, 80, 170),
    "white": (240, 240, 240),
    "grey": (128, 128, 128),
    "black": (15, 15, 15),
    "beige": (215, 195, 160),
}


def _canvas(rgb: tuple[int, int, int] = (128, 128, 128), h: int = 60, w: int = 90) -> np.ndarray:
    return np.tile(np.array(rgb, np.uint8), (h, w, 1))


@pytest.mark.parametrize("name", sorted(SWATCHES))
def test_swatch_is_named_by_its_colour(name: str) -> None:
    """A plain swatch of a typical shade gets that colour's name."""
    reading = dominant_colour(_canvas(SWATCHES[name]))
    assert reading is not None and reading.name == name and reading.fraction == 1.0


def test_darker_shading_keeps_the_name() -> None:
    """A shadowed blue (60 % brightness) is still blue, as lit objects in a render are."""
    shaded = tuple(int(c * 0.6) for c in SWATCHES["blue"])
    assert dominant_colour(_canvas(shaded)).name == "blue"


def test_every_swatch_name_is_a_known_colour() -> None:
    """The classes returned are indices into COLOUR_NAMES."""
    assert set(SWATCHES) == set(COLOUR_NAMES)
    assert colour_classes(_canvas()).max() < len(COLOUR_NAMES)


def test_dominant_colour_of_a_box_ignores_what_is_outside() -> None:
    """A red square on grey is red inside its box and grey for the whole image."""
    image = _canvas()
    image[10:30, 10:30] = SWATCHES["red"]
    assert dominant_colour(image, box=(10, 10, 30, 30)).name == "red"
    assert dominant_colour(image).name == "grey"


def test_dominant_colour_of_a_mask_counts_only_masked_pixels() -> None:
    """With a mask only the object's pixels vote, and shares add up to one."""
    image = _canvas()
    image[:, :20] = SWATCHES["green"]
    mask = np.zeros(image.shape[:2], bool)
    mask[5:15, 2:12] = True
    reading = dominant_colour(image, mask=mask)
    assert reading.name == "green"
    assert sum(reading.shares.values()) == pytest.approx(1.0)


def test_inner_fraction_drops_background_at_box_edges() -> None:
    """A loose box around a small yellow blob is yellow once only its middle is read."""
    image = _canvas()
    image[25:35, 40:50] = SWATCHES["yellow"]
    box = (30.0, 15.0, 60.0, 45.0)
    assert dominant_colour(image, box=box).name == "grey"
    assert dominant_colour(image, box=box, inner=0.4).name == "yellow"


def test_dominant_colour_of_an_empty_region_is_none() -> None:
    """A box outside the image holds no pixel and gives no reading."""
    assert dominant_colour(_canvas(), box=(200, 200, 300, 300)) is None


def test_reading_carries_position_of_the_region() -> None:
    """A region in the right third of the image is reported on the right."""
    image = _canvas()
    reading = dominant_colour(image, box=(70, 10, 88, 20))
    assert reading.position == "right"
    assert reading.centroid == pytest.approx((79.0, 15.0))  # the box centre in pixel-edge coordinates


@pytest.mark.parametrize(("u", "where"), [(0, "left"), (29.9, "left"), (30, "centre"), (59.9, "centre"),
                                          (60, "right"), (89, "right")])
def test_horizontal_position_splits_the_image_in_thirds(u: float, where: str) -> None:
    """Columns are left, centre or right by which third of the width they fall in."""
    assert horizontal_position(u, 90) == where


def test_find_colour_reports_centroid_and_side() -> None:
    """A blue patch on the left is found, with its share of the image and its centroid."""
    image = _canvas()
    image[20:40, 0:10] = SWATCHES["blue"]
    region = find_colour(image, "blue")
    assert region is not None and region.position == "left"
    assert region.fraction == pytest.approx(200 / 5400)
    assert region.centroid == pytest.approx((5.0, 30.0))


def test_find_colour_below_the_threshold_is_absent() -> None:
    """A colour on fewer than 1 % of the pixels counts as absent (seed 002's threshold)."""
    image = _canvas()
    image[0:5, 0:5] = SWATCHES["red"]  # 25 of 5400 pixels
    assert find_colour(image, "red") is None
    assert find_colour(image, "red", min_fraction=0.004) is not None


@pytest.mark.parametrize("shade", [1.0, 0.8])
def test_simulator_palette_is_named_back_when_lit_or_turned_from_the_light(shade: float) -> None:
    """Every colour of the simulator's palette, at full light and at 80 %, gets its canonical name."""
    from missiontree.backends.sim.schema import COLOR_NAMES

    for name, rgb in COLOR_NAMES.items():
        if name in ("silver", "light grey") and shade == 1.0:
            continue  # 190 grey under full light reads as white: the two overlap in HSV
        swatch = _canvas(tuple(int(c * shade) for c in rgb))
        assert dominant_colour(swatch).name == canonical_colour(name), name


def test_aliases_name_the_same_colour() -> None:
    """'Gray' and 'grey' select the same pixels."""
    assert canonical_colour(" Gray ") == "grey"
    image = _canvas()
    assert (colour_mask(image, "gray") == colour_mask(image, "grey")).all()


def test_unknown_colour_name_lists_the_known_ones() -> None:
    """Asking for a colour the mapper does not know says which it knows."""
    with pytest.raises(ValueError, match="unknown colour 'chartreuse'; known: black, grey"):
        colour_mask(_canvas(), "chartreuse")
