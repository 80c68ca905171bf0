"""Messages joined from parts (acquisition.errors.join_sentences): one full stop between
sentences, never two, and no sentence said twice (issue 22: the quarry's refusal ended
"unchanged.. The vehicle's mission is unchanged.")."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from acquisition.errors import join_sentences
from acquisition.transfer_outcome import MissionState, MissionTransferError

VOCABULARY = ["the", "vehicle", "mission", "is", "unchanged", "sent", "3.5 m"]
words = st.lists(st.sampled_from(VOCABULARY), min_size=1)
sentence = words.map(lambda w: " ".join(w).capitalize())
part = st.lists(sentence, min_size=1, max_size=3).flatmap(
    lambda ss: st.sampled_from([". ".join(ss), ". ".join(ss) + "."])
)


def test_the_quarry_refusal_says_its_state_once() -> None:
    error = MissionTransferError(
        "upload refused: 1836 items and this vehicle holds at most 724: 1112 too many. Split the "
        "survey into sorties. Nothing was sent: the vehicle's mission is unchanged.",
        mission_state=MissionState.UNCHANGED,
    )
    text = str(error)
    assert ".." not in text
    assert text.endswith("Nothing was sent: the vehicle's mission is unchanged.")
    assert text.lower().count("mission is unchanged") == 1


def test_a_part_without_a_full_stop_gets_one() -> None:
    assert join_sentences("no heartbeat on tcp://127.0.0.1:5760", "Nothing was sent.") == (
        "no heartbeat on tcp://127.0.0.1:5760. Nothing was sent."
    )
    assert join_sentences("altitude 3.5 m.", "Lower it") == "altitude 3.5 m. Lower it"
    assert join_sentences("", "Only this.", "") == "Only this."


@given(parts=st.lists(part, min_size=1, max_size=4))
def test_joined_parts_have_single_stops_and_no_repeated_sentence(parts: list[str]) -> None:
    text = join_sentences(*parts)
    assert ".." not in text
    said = [s.rstrip(".").lower() for s in text.split(". ")]
    assert len(said) == len(set(said))
    for p in parts:  # nothing said is lost
        for s in p.rstrip(".").split(". "):
            assert s.lower() in text.lower()
