"""A campaign in memory with its periodic records cut into cycles (what :func:`~.campaign.read_campaign` does
with ``segment="cycles"`` as it reads a directory; the rules and the detection: :mod:`.records`)."""
from __future__ import annotations

from dataclasses import replace

from .campaign import Campaign, make_campaign
from .errors import DataError
from .records import SEGMENT_CHOICES, cut_record


def segmented(campaign: Campaign, segment: str | None) -> Campaign:
    """``campaign`` with every whole record cut into its cycles found from alpha (``segment="cycles"``), or as it
    is (``None`` or ``"none"``: a campaign in memory was segmented, or not, when it was read). Maneuvers that are
    cycles already (``record`` set) and steady points stay as they are. A cycle too short for the campaign's rule is an error."""
    if segment is not None and segment not in SEGMENT_CHOICES:
        raise DataError(f"segment must be one of {', '.join(SEGMENT_CHOICES)}, not {segment!r}")
    if segment != "cycles":
        return campaign
    cbar = float(campaign.aircraft["cbar"])
    maneuvers, pieces = [], []
    for m, rows in zip(campaign.maneuvers, campaign.data.segment_slices()):
        columns = {k: v[rows] for k, v in campaign.data.columns.items()}
        if m.record or m.steady:   # a cycle already, or steady points (no cycle to cut)
            maneuvers.append(m)
            pieces.append(columns)
            continue
        where = str(campaign.directory / m.file) if campaign.directory is not None else f"{campaign.name}:{m.id}"
        for piece_id, piece in cut_record(columns, m.id, where, campaign.length_rules.for_kind(m.kind), cbar):
            maneuvers.append(replace(m, id=piece_id, record=m.id, frequency=None))
            pieces.append(piece)
    out = make_campaign(campaign.name, campaign.aircraft, maneuvers, pieces, campaign.extra)
    return replace(out, directory=campaign.directory, cutoffs_hz=dict(campaign.cutoffs_hz),
                   length_rules=campaign.length_rules)
