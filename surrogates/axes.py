"""The axes of a mechanical surrogate: name and units of the loading coordinate ``x`` and the response ``y``.

A mechanical surrogate maps the six shell parameters and a loading coordinate to a response, per loading
protocol (docs/physics.md section 1 for the DPD units):

* compression: ``x`` = imposed total plate displacement [DPD length], ``y`` = force [DPD force];
* indentation: ``x`` = applied pole force [DPD force], ``y`` = indentation depth [DPD length].

Both the training side (:class:`bubblecal.surrogates.training.TrainingSet`, the export) and the
development bundle (:mod:`bubblecal.surrogates.synthetic_bundle`) write these names and units into the
surrogate metadata (``input_names``, ``input_units``, ``output_name``, ``output_units``).
"""

from __future__ import annotations

__all__ = ["X_INFO", "Y_INFO"]

#: (name, units) of the loading coordinate, per loading protocol.
X_INFO: dict[str, tuple[str, str]] = {"compression": ("displacement", "DPD length"),
                                      "indentation": ("force", "DPD force")}
#: (name, units) of the response, per loading protocol.
Y_INFO: dict[str, tuple[str, str]] = {"compression": ("force", "DPD force"),
                                      "indentation": ("displacement", "DPD length")}
