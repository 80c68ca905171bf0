"""acquisition's branch of the sfap error tree (root: planner.errors.SfapError)."""

from __future__ import annotations

import re

from planner.errors import InputError, SfapError

_SENTENCE_END = re.compile(r"(?<=[.!?])\s+")


def _said(sentence: str) -> str:
    """A sentence as compared for repetition: lower case, no closing stop, spaces folded."""
    return " ".join(sentence.lower().rstrip(".!? ").split())


def join_sentences(*parts: str) -> str:
    """``parts`` joined into one message, each as sentences: a part that does not end with a
    full stop (or ! or ?) gets one before the next part, and a sentence already said (the
    same words, whatever its case or closing stop, alone or at the end of an earlier
    sentence) is left out. ``join_sentences("refused: 4 too many. The mission is unchanged.",
    "The mission is unchanged.")`` says it once, with one full stop."""
    text = ""
    for part in parts:
        part = part.strip()
        if not part:
            continue
        kept: list[str] = []
        for sentence in _SENTENCE_END.split(part):
            said = _said(sentence)
            before = [_said(s) for s in _SENTENCE_END.split(text) + kept]
            if said and any(b == said or b.endswith(" " + said) for b in before):
                continue
            kept.append(sentence)
        if not kept:
            continue
        if text and not text.endswith((".", "!", "?", ":", "\n")):
            text += "."
        text = f"{text} {' '.join(kept)}" if text and not text.endswith("\n") else text + " ".join(kept)
    return text


class AcquisitionError(SfapError):
    """Something went wrong talking to a vehicle or reading its logs (exit code 1)."""


class LinkError(AcquisitionError):
    """A MAVLink link could not be opened, heard nothing, or dropped."""


class TransferError(AcquisitionError):
    """A mission transfer failed; the message states the vehicle's mission state."""


class VerificationError(TransferError):
    """The mission read back from the vehicle differs from the one sent."""


class TelemetryError(InputError):
    """A flight log cannot be read (wrong format, empty, no usable messages)."""


class GeotagError(AcquisitionError):
    """Frames could not be matched or tagged."""
