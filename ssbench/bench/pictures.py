"""What a sweep draws of each configuration when its file says ``images: true``: the pass's image and its error
map, two small PNGs per configuration under the sweep folder's ``img/``, named by ``config_id``.

Each effect declares a :class:`Pictures` (:attr:`ssbench.bench.effects.Effect.pictures`): the function that draws
an evaluation, the captions, and how to read the error map — a colour bar (:class:`ColourScale`) or the class
colours of :data:`ssbench.metrics.implicit.CLASS_COLORS`. The report's sweep explorer shows these files beside the
configuration's row and its point on the error–time plot; every picture uses the conventions of
:mod:`ssbench.pictures`, so it reads like the report's own figures.
"""
from __future__ import annotations

import dataclasses
import os
from typing import Any, Callable, Optional

__all__ = ["ColourScale", "Pictures", "AO_PICTURES", "SSR_PICTURES", "IMPLICIT_PICTURES", "write_pictures", "ao_pictures", "ssr_pictures",
           "implicit_pictures"]

#: saturation of the AO signed error and of the SSR colour error (the report's sections use the same)
ERROR_RANGE = 0.5


@dataclasses.dataclass(frozen=True)
class ColourScale:
    """A false-colour scale: ``cmap`` over ``[vmin, vmax]``, what the values are (``label``, with units) and what
    the two ends mean (``low``, ``high``)."""

    cmap: str
    vmin: float
    vmax: float
    label: str
    low: str = ""
    high: str = ""


@dataclasses.dataclass(frozen=True)
class Pictures:
    """How a sweep draws one configuration of an effect.

    Attributes:
        draw: ``draw(evaluation) -> (image, error)``, both ``(H, W, 3)`` uint8 (``error`` ``None`` when the
            evaluation scored nothing).
        image, error: captions of the two pictures.
        scale: the error map's colour scale; ``None`` when it is a class map (``classes`` set).
        classes: ``"implicit"`` when the error map shows :data:`ssbench.metrics.implicit.CLASS_COLORS`.
    """

    draw: Callable[[Any], tuple]
    image: str
    error: str
    scale: Optional[ColourScale] = None
    classes: Optional[str] = None


def ao_pictures(ev) -> tuple:
    """The pass's AO (after its blur) in grey, and its signed error against the cosine ground truth on ``RdBu``."""
    from ..pictures import ao_rgb, error_rgb
    mask = ev.gbuffer.mask
    return ao_rgb(ev.ao, mask), error_rgb(ev.ao.float() - ev.references["cos"].ao.float(), mask, ERROR_RANGE)


def ssr_pictures(ev) -> tuple:
    """The pass's reflected colour (fades applied, sRGB), and its raw colour's mean absolute RGB error against the
    mirror reflection where the pass can be blamed (:func:`ssbench.pictures.scored_error_rgb`)."""
    from ..metrics.ssr import color_error_map
    from ..pictures import color_rgb, scored_error_rgb
    res, truth = ev.result, ev.truth
    valid = truth.valid.bool()
    err = color_error_map(res.raw_color, truth.radiance)
    return color_rgb(res.color, valid), scored_error_rgb(err, ev.classes, valid, ERROR_RANGE)


def implicit_pictures(ev) -> tuple:
    """The last frame's shaded hits, and its class map against the certified first hit (``None`` when the last
    frame was not scored)."""
    from ..pictures import implicit_class_rgb, implicit_color_rgb
    image = implicit_color_rgb(ev.result, ev.cameras[ev.last], ev.scene)
    classes = ev.classes.get(ev.last)
    return image, None if classes is None else implicit_class_rgb(classes)


#: the AO effect's pictures (named by its :attr:`ssbench.bench.effects.Effect.pictures`)
AO_PICTURES = Pictures(ao_pictures, "AO of the pass (grey, after its blur)", "AO − ray-traced cosine AO",
                       ColourScale("RdBu", -ERROR_RANGE, ERROR_RANGE, "AO − GT", "too dark", "too bright"))
#: the SSR effect's pictures
SSR_PICTURES = Pictures(ssr_pictures, "reflected colour (fades applied)",
                        "|raw colour − mirror reflection| (grey: nothing to blame the pass for)",
                        ColourScale("magma", 0.0, ERROR_RANGE, "mean |Δ RGB| (linear)", "exact", "wrong"))
#: the implicit effect's pictures
IMPLICIT_PICTURES = Pictures(implicit_pictures, "shaded first hits (last frame)",
                             "classes against the certified first hit", classes="implicit")


def write_pictures(pictures: Pictures, evaluation, folder: str, config_id: str) -> dict:
    """Draw ``evaluation`` and write ``folder/img/<config_id>.png`` and ``<config_id>_error.png`` (atomically);
    raises ``ValueError`` when ``draw`` returns anything but ``(H, W, 3)`` uint8 arrays; returns ``{"image": "img/<id>.png", "error": ... or None}`` relative to ``folder`` (a row's ``images``)."""
    from ..io import write_rgb_png
    image, error = pictures.draw(evaluation)
    out: dict = {}
    for key, rgb, name in (("image", image, f"{config_id}.png"), ("error", error, f"{config_id}_error.png")):
        if rgb is None:
            out[key] = None
            continue
        write_rgb_png(os.path.join(folder, "img", name), rgb)
        out[key] = f"img/{name}"
    return out
