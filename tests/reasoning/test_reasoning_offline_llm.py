"""Tests of the offline intent stand-in and reference parsing."""

from __future__ import annotations

from typing import Any

import pytest

from missiontree.errors import ModelError
from missiontree.reasoning.checks import chat_checked
from missiontree.reasoning.embedder import MiniLMEmbedder
from missiontree.reasoning.phrases import parse_reference, split_relation
from missiontree.reasoning.prompts import intent_messages
from missiontree.reasoning.protocols import Message
from missiontree.reasoning.providers.offline_llm import OfflineLanguageModel
from missiontree.reasoning.schemas import IntentResolution, ReferenceParse

LABELS = ["bottle", "cup", "sofa", "chair", "backpack", "laptop", "sink", "tv", "book"]


@pytest.fixture(scope="module")
def llm() -> OfflineLanguageModel:
    return OfflineLanguageModel(MiniLMEmbedder())


def obj(id_: str, label: str, x: float, y: float, *attributes: str, **extra: Any) -> dict[str, Any]:
    return {"id": id_, "label": label, "x": x, "y": y, "attributes": list(attributes), **extra}


SCENE = [
    obj("bottle_1", "bottle", 1.0, 0.0, "pink", room="kitchen"),
    obj("cup_1", "cup", 1.5, 0.5, "white", room="kitchen"),
    obj("sink_1", "sink", 2.0, 0.0, "grey", room="kitchen"),
    obj("sofa_1", "sofa", 6.0, 4.0, "green", room="office", yaw=0.0),
    obj("laptop_1", "laptop", 7.0, 4.0, "grey", room="office"),
    obj("laptop_2", "laptop", 5.0, 4.0, "black", room="office"),
    obj("backpack_1", "backpack", 3.0, 3.0, "grey", room="office"),
    obj("backpack_2", "backpack", 8.0, 1.0, "red", room="office"),
    obj("chair_1", "chair", 4.0, 2.0, "blue", room="office"),
    obj("tv_1", "tv", 9.0, 4.0, "black", room="office"),
]


def resolve(llm: OfflineLanguageModel, request: str) -> IntentResolution:
    return IntentResolution.model_validate_json(llm.chat(intent_messages(request, SCENE), IntentResolution))


def test_thirsty_names_bottle_and_cup(llm: OfflineLanguageModel) -> None:
    """"I am thirsty" names the bottle and the cup (NAIS Table II), not the sink."""
    assert set(resolve(llm, "I am thirsty").candidates) == {"bottle_1", "cup_1"}


def test_need_with_nothing_serving_it_names_nothing(llm: OfflineLanguageModel) -> None:
    """A need no scene object serves gives no candidates and says why."""
    answer = resolve(llm, "I need to recharge the car battery with jumper cables")
    assert answer.candidates == [] and "no object in the scene serves" in answer.reason


@pytest.mark.parametrize(("request_", "lacking"), [
    ("I want to go swimming", "swimming pool"),       # shares "water" with the bottle and the cup
    ("I want to wash my clothes", "washing machine"),  # shares "washing" with the sink
    ("I feel dirty and need a bath", "bathtub"),
])
def test_need_calling_for_something_the_scene_lacks_names_nothing(llm: OfflineLanguageModel, request_: str,
                                                                  lacking: str) -> None:
    """A need whose fitting object the scene lacks is unserved, even when a present object shares a word."""
    answer = resolve(llm, request_)
    assert answer.candidates == [] and lacking in answer.reason


@pytest.mark.parametrize(("request_", "expected"), [
    ("I need to wash my hands", {"sink_1"}),
    ("I need coffee", {"cup_1"}),
    ("I would like to watch a film", {"tv_1"}),
])
def test_lacking_classes_do_not_shadow_present_ones(llm: OfflineLanguageModel, request_: str,
                                                    expected: set[str]) -> None:
    """The classes a scene may lack only veto a weak fit: needs a present object serves still find it."""
    assert expected <= set(resolve(llm, request_).candidates)


def test_a_lacking_class_present_in_the_scene_is_a_candidate(llm: OfflineLanguageModel) -> None:
    """When the scene holds the class a need calls for (a shower), it is the answer, not a veto."""
    scene = [*SCENE, obj("shower_1", "shower", 3.0, 1.0, "white", room="bathroom")]
    answer = IntentResolution.model_validate_json(
        llm.chat(intent_messages("I want to take a shower", scene), IntentResolution))
    assert answer.candidates[:1] == ["shower_1"]


def test_grey_backpack_picks_the_grey_one(llm: OfflineLanguageModel) -> None:
    """"I want the grey backpack" names only the grey backpack, with the parsed reference."""
    answer = resolve(llm, "I want the grey backpack")
    assert answer.candidates == ["backpack_1"]
    assert answer.reference == ReferenceParse(label="backpack", attributes=["grey"])


def test_colour_synonym_and_plural(llm: OfflineLanguageModel) -> None:
    """"gray" folds to grey and "laptops" to laptop."""
    assert resolve(llm, "show me the gray laptops").candidates == ["laptop_1"]


def test_missing_attribute_names_nothing(llm: OfflineLanguageModel) -> None:
    """A purple backpack that does not exist gives no candidates and lists what exists."""
    answer = resolve(llm, "bring me the purple backpack")
    assert answer.candidates == [] and "'grey', 'red'" in answer.reason


def test_in_front_of_uses_the_anchor_heading(llm: OfflineLanguageModel) -> None:
    """"the laptop in front of the sofa" picks the laptop ahead of the sofa (yaw 0 faces +x), not behind."""
    answer = resolve(llm, "find the laptop in front of the sofa")
    assert answer.candidates == ["laptop_1"]
    assert answer.reference is not None and answer.reference.relation == "in_front_of"


def test_behind_picks_the_other_side(llm: OfflineLanguageModel) -> None:
    """"behind the sofa" picks the laptop on the sofa's back side."""
    assert resolve(llm, "the laptop behind the couch").candidates == ["laptop_2"]


def test_in_a_room_filters_by_room(llm: OfflineLanguageModel) -> None:
    """"the cup in the kitchen" filters by the objects' room."""
    assert resolve(llm, "the cup in the kitchen").candidates == ["cup_1"]


def test_answers_pass_grounding_checks(llm: OfflineLanguageModel) -> None:
    """The stand-in's answers name only ids of the scene, so the checks pass first time."""
    ids = {o["id"] for o in SCENE}
    answer = chat_checked(llm, intent_messages("I am bored", SCENE), IntentResolution, valid_ids=ids)
    assert answer.attempts == 1 and answer.value.candidates


def test_unreadable_conversation_names_the_fix(llm: OfflineLanguageModel) -> None:
    """A conversation not built by intent_messages is refused, naming what to use instead."""
    with pytest.raises(ModelError, match="offline_llm: cannot read the conversation.*intent_messages"):
        llm.chat([Message("user", "hello")], IntentResolution)


def test_reference_parse_schema(llm: OfflineLanguageModel) -> None:
    """Asked for a ReferenceParse, it returns the parsed phrase."""
    text = llm.chat(intent_messages("the red backpack next to the chair", SCENE), ReferenceParse)
    assert ReferenceParse.model_validate_json(text) == ReferenceParse(
        label="backpack", attributes=["red"], relation="next_to", anchor="chair")


def test_split_relation_prefers_the_longest_phrase() -> None:
    """"in front of" wins over "in" at the same place."""
    assert split_relation("the laptop in front of the sofa") == ("the laptop", "in_front_of", "the sofa")


def test_parse_reference_without_a_known_label_is_none() -> None:
    """A need names no label, so it is not a reference."""
    assert parse_reference("I am thirsty", LABELS) is None


def test_parse_reference_reads_size_and_synonyms() -> None:
    """"the big mug near the couch" → cup, large, near sofa."""
    assert parse_reference("the big mug near the couch", LABELS) == ReferenceParse(
        label="cup", attributes=["large"], relation="near", anchor="sofa")


def test_a_strong_server_stands_in_for_a_lacking_better_one(llm: OfflineLanguageModel) -> None:
    """Bored with no TV in the scene: the laptop serves the same need strongly and is the answer."""
    scene = [o for o in SCENE if o["label"] != "tv"]
    reply = llm.chat(intent_messages("I am bored", scene), IntentResolution)
    assert {"laptop_1", "laptop_2"} <= set(IntentResolution.model_validate_json(reply).candidates)



DESKS_AND_TABLES = [obj("desk_1", "desk", 1.0, 0.0), obj("table_1", "table", 3.0, 0.0),
                    obj("counter_1", "counter", 5.0, 0.0), obj("laptop_1", "laptop", 7.0, 0.0),
                    obj("backpack_1", "backpack", 9.0, 0.0)]


@pytest.mark.parametrize(("request_", "expected"), [
    ("the desk", ["desk_1"]), ("the table", ["table_1"]), ("go to the escritoire", ["desk_1"]),
    ("the writing table", ["desk_1"]), ("take me to the checkout counter", ["counter_1"])])
def test_a_kind_names_the_nearest_class_above_it(llm: OfflineLanguageModel, request_: str,
                                                 expected: list[str]) -> None:
    """A scene listing desks and tables keeps them apart, and a kind of desk (WordNet) is a desk."""
    assert llm.resolve(request_, DESKS_AND_TABLES).candidates == expected


@pytest.mark.parametrize(("request_", "expected"), [
    ("can you show me the personal computer", ["laptop_1"]), ("take me to the container", ["backpack_1"]),
    ("where is the furniture", ["counter_1", "desk_1", "table_1"])])
def test_a_more_general_word_names_the_classes_under_it(llm: OfflineLanguageModel, request_: str,
                                                        expected: list[str]) -> None:
    """A WordNet hypernym of a class (a pc, a container, furniture) names the scene's classes under it."""
    assert sorted(llm.resolve(request_, DESKS_AND_TABLES).candidates) == expected


def test_a_room_named_before_the_object_without_a_relation_word_places_it() -> None:
    """"Go to the bathroom and find the sink" asks for the sink in the bathroom."""
    parsed = parse_reference("Go to the bathroom and find the sink.", ["sink", "toilet"],
                             ["bathroom", "kitchen"])
    assert parsed is not None
    assert (parsed.label, parsed.relation, parsed.anchor) == ("sink", "in", "bathroom")
