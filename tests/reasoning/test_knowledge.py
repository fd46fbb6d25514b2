"""The shipped intent knowledge and how the offline reasoner uses it (WordNet words, affordances)."""

from __future__ import annotations

import pytest

from missiontree.reasoning.embedder import MiniLMEmbedder
from missiontree.reasoning.knowledge import STRONG, knowledge
from missiontree.reasoning.providers.offline_llm import OfflineLanguageModel

LABELS = ["bottle", "cup", "sofa", "chair", "bed", "tv", "laptop", "backpack", "umbrella", "sink", "book"]


@pytest.fixture(scope="module")
def model() -> OfflineLanguageModel:
    return OfflineLanguageModel(MiniLMEmbedder())


def scene() -> list[dict[str, str]]:
    return [{"id": f"{label}_1", "label": label} for label in LABELS]


def test_inflected_word_is_read_through_its_dictionary_form() -> None:
    """"emails" is read as the e-mail word of the work need."""
    reading = knowledge().read("I need to answer some emails")
    assert reading.needs["work"][1] == "emails"


def test_wordnet_neighbour_of_a_need_word_is_understood(model: OfflineLanguageModel) -> None:
    """"famished" (WordNet: similar to hungry) and "beverage" reach the right classes."""
    assert model.resolve("I could use a beverage", scene()).candidates == ["bottle_1", "cup_1"]
    answer = model.resolve("I am famished", [*scene(), {"id": "fridge", "label": "refrigerator"}])
    assert answer.candidates == ["fridge"]


def test_answering_emails_goes_to_the_laptop(model: OfflineLanguageModel) -> None:
    """A need the embedding alone missed (similarity 0.19) goes to the laptop, naming the word."""
    answer = model.resolve("I need to answer some emails", scene())
    assert answer.candidates == ["laptop_1"]
    assert "emails" in answer.reason


def test_unknown_thing_is_served_by_nothing(model: OfflineLanguageModel) -> None:
    """"bring me a unicorn" names no need and no known object: no candidate, and the reason says so."""
    answer = model.resolve("bring me a unicorn", scene())
    assert answer.candidates == []
    assert "unicorn" in answer.reason


def test_general_word_covers_every_label_under_it(model: OfflineLanguageModel) -> None:
    """A WordNet hypernym of several labels ("seat") offers each of them present, before other rest places."""
    answer = model.resolve("take me to some kind of seat", scene())
    assert set(answer.candidates[:2]) == {"sofa_1", "chair_1"}


def test_weak_stand_in_is_not_offered_beside_strong_ones(model: OfflineLanguageModel) -> None:
    """For thirst the bottle and cup are offered, the sink (0.4) is not."""
    assert "sink_1" not in model.resolve("I am thirsty", scene()).candidates


def test_synonym_from_wordnet_names_the_class() -> None:
    """A WordNet word of a class (settee) folds to it, a colour word never does."""
    from missiontree.reasoning.phrases import fold_label

    assert fold_label("settee") == "sofa"
    assert fold_label("red") == "red"


def test_compound_naming_something_else_is_not_its_object(model: OfflineLanguageModel) -> None:
    """A flower bed is no bed: the compound is read whole, and nothing serves it."""
    answer = model.resolve("take me to the flower bed", scene())
    assert answer.candidates == [] and "flower bed" in answer.reason


def test_hyphenated_word_is_read_whole(model: OfflineLanguageModel) -> None:
    """"world-weary" (WordNet: bored) is read as one word, not as "weary" (tired)."""
    answer = model.resolve("I feel so world-weary", scene()).candidates
    assert answer[0] == "tv_1" and not {"sofa_1", "chair_1", "bed_1"} & set(answer)


def test_word_reached_through_a_rare_sense_does_not_mean_the_need() -> None:
    """"cut" is a kind of food only in a rare sense of it (a cut of meat): it expresses no hunger."""
    assert "eat" not in knowledge().read("I need a cut").needs


@pytest.mark.parametrize(("word", "need"),
                         [("tipple", "drink"), ("hit the sack", "sleep"), ("starving", "eat")])
def test_word_defined_by_a_need_is_read_as_it(word: str, need: str) -> None:
    """A word whose WordNet definition says the need ("tipple: drink moderately") means that need."""
    reading = knowledge().read(f"I want to {word}")
    assert need in reading.needs and reading.needs[need][0] >= STRONG


def test_a_kind_of_beverage_serves_thirst_strongly() -> None:
    """A deep hyponym of a need's sense (rum, under beverage) still serves it: a bottle is a strong choice."""
    kb = knowledge()
    assert kb.score("bottle", kb.read("I'm in need of rum"))[0] >= STRONG


def test_a_definition_that_negates_the_need_is_not_read() -> None:
    """'undrinkable' (not fit to drink) does not mean thirst."""
    assert "drink" not in knowledge().read("it is undrinkable").needs


@pytest.mark.parametrize(("request_", "need"), [("something to divert me", "entertainment"),
                                                ("a thunderstorm is coming", "rain")])
def test_a_needs_most_frequent_sense_is_read(request_: str, need: str) -> None:
    """The most frequent sense of a need's verb ("amuse, divert") and storms (rain) are read as the need."""
    assert need in knowledge().read(request_).needs


def test_knowledge_file_over_its_limit_is_refused_before_reading(tmp_path, monkeypatch) -> None:
    """A knowledge file larger than its limit is a ConfigError naming the file, not read whole."""
    from missiontree.errors import ConfigError
    from missiontree.reasoning import knowledge as module

    big = tmp_path / "intent_knowledge.json"
    big.write_bytes(b" " * 2048)
    monkeypatch.setattr(module, "MAX_KNOWLEDGE_BYTES", 1024)
    with pytest.raises(ConfigError, match="intent_knowledge.json"):
        module.read_knowledge(big)


def test_knowledge_file_of_the_wrong_shape_is_a_config_error(tmp_path) -> None:
    """A JSON file that is no knowledge document is a ConfigError naming the file."""
    from missiontree.errors import ConfigError
    from missiontree.reasoning.knowledge import read_knowledge

    wrong = tmp_path / "k.json"
    wrong.write_text('{"needs": []}', encoding="utf-8")
    with pytest.raises(ConfigError, match="k.json"):
        read_knowledge(wrong)


def test_a_general_word_beside_a_need_names_nothing_of_its_own() -> None:
    """In "in any case, I'm thirsty" the case (a kind of container) names no suitcase; alone it does."""
    assert "suitcase" not in knowledge().read("In any case, I'm thirsty").named
    assert "suitcase" in knowledge().read("take me to the case").named


@pytest.mark.parametrize(("request_", "need"), [
    ("Gosh, I'm dead after today.", "rest"), ("I feel empty, it's been hours.", "eat"),
    ("Time for a nightcap.", "drink"), ("A shandy would be lovely.", "drink")])
def test_wordnet_state_adjectives_and_servings_of_drink_are_read(request_: str, need: str) -> None:
    """A bodily-state adjective in a less frequent sense (dead: tired) and a kind of drink are read."""
    assert need in knowledge().read(request_).needs


@pytest.mark.parametrize(("word", "need"), [("sleepily", "sleep"), ("hungrily", "eat"),
                                            ("thirstier", "drink"), ("hungriest", "eat")])
def test_adverbs_and_comparatives_are_read_through_their_adjective(word: str, need: str) -> None:
    """An adverb (-ily) or a comparative (-ier, -iest) is read as the adjective it comes from."""
    assert need in knowledge().read(f"I look at the fridge {word}").needs


@pytest.mark.parametrize("request_", ["I'm rested", "I'm so rested now", "I feel fed up", "I feel pooped"])
def test_a_participle_of_a_needs_own_verb_said_of_oneself_is_no_need(request_: str) -> None:
    """'I'm rested' says the rest is behind: the participle of a need's own verb is not read as the need."""
    assert knowledge().read(request_).needs == {}


def test_a_participle_of_a_verb_that_causes_the_state_still_says_it() -> None:
    """'I'm tuckered out' (tucker: to tire someone) still says tiredness; 'I have eaten' is no copula."""
    assert "rest" in knowledge().read("I'm tuckered out").needs


def test_a_word_saying_two_needs_equally_chooses_nothing(model: OfflineLanguageModel) -> None:
    """'A documentary' is to watch or to print: with a TV and a printer and nothing serving both, no guess."""
    objects = [{"id": "tv_1", "label": "tv"}, {"id": "printer_1", "label": "printer"}]
    answer = model.resolve("a documentary please", objects)
    assert answer.candidates == [] and "equally" in answer.reason


def test_a_weaker_second_need_adds_no_class_beside_the_stated_one(model: OfflineLanguageModel) -> None:
    """'Watch a documentary': the TV, not the printer (print is only the documentary's other sense)."""
    objects = [{"id": "tv_1", "label": "tv"}, {"id": "printer_1", "label": "printer"}]
    assert model.resolve("I'd like to watch a documentary", objects).candidates == ["tv_1"]


def test_a_word_saying_two_needs_keeps_the_class_serving_both(model: OfflineLanguageModel) -> None:
    """'Swallow' is to eat or to drink: the refrigerator serves both strongly, the bottle only drink."""
    objects = [{"id": "bottle_1", "label": "bottle"}, {"id": "fridge_1", "label": "refrigerator"}]
    assert model.resolve("I want to swallow something", objects).candidates == ["fridge_1"]


def test_two_needs_said_by_two_words_are_both_served(model: OfflineLanguageModel) -> None:
    """'I'm thirsty and bored' says both: the bottle and the TV are both candidates."""
    objects = [{"id": "bottle_1", "label": "bottle"}, {"id": "tv_1", "label": "tv"}]
    assert set(model.resolve("I'm thirsty and bored", objects).candidates) == {"bottle_1", "tv_1"}


def test_a_bookcase_names_the_bookshelf() -> None:
    """A room's bookshelf is WordNet's bookcase (furniture with shelves): that word names it."""
    assert knowledge().read("the bookcase").named.get("bookshelf", (0.0, ""))[0] >= 0.9


@pytest.mark.parametrize("word", ["settee", "davenport", "daybed", "throne"])
def test_a_word_whose_near_senses_name_two_classes_names_neither(word: str) -> None:
    """'Davenport' is a sofa, then a desk; 'throne' a chair of state, then a toilet: neither is guessed."""
    assert knowledge().read(f"the {word}").named == {}


def test_a_word_naming_another_class_only_in_a_rare_sense_names_its_first() -> None:
    """'Couch' is a sofa first (a psychiatrist's bed only third): it names the sofa."""
    assert set(knowledge().read("the couch").named) == {"sofa"}
