"""What the citations on the block reference pages refer to: plain data, for their Sources section.

The pages in ``docs/blocks/`` (:func:`loopworks.blocks.reference.markdown`) cite the two
specifications loopworks is implemented from. They are internal documents, not shipped with
the package, so every citation is explained here:

* ``vendor-blocks``: *Vendor PID function blocks: emulation specification* (GE PACSystems,
  Siemens S5, Emerson E2 and DeltaV blocks), with its reference list [R1]..[R61] (its
  section 9) and the seeds (vendor excerpts) it was written from;
* ``plant-and-tuning``: *Valve nonlinearity models, stiction compensation, relay auto-tuning and
  loop metrics: implementation reference*, whose references (its section 8) are cited by
  author and year, so they need no table here.

``SECTIONS`` gives each section's title in plain words (transcribed from the headings of the
two documents, tags and source lists removed), ``REFERENCES`` the bibliographic entries of
vendor-blocks' reference list (title, vendor, document number, pages; the URLs of the mirrors
left out), ``SEEDS`` the vendor excerpts, ``TAGS`` the confidence tags of each document's
section 0 (vendor-blocks) or preamble (plant-and-tuning; the two documents give [V] different
meanings), ``PROJECT_TAGS`` loopworks' own tags, and ``kind_document`` the document a bare
"spec X.Y" means on each kind's page. A page that cites anything missing here fails
``tests/test_docs.py``: add the entry when adding the citation.
"""

from __future__ import annotations

VENDOR = "vendor-blocks"
PLANT = "plant-and-tuning"

DOCUMENTS: dict[str, str] = {
    VENDOR: "Vendor PID function blocks: emulation specification (GE PACSystems PID, "
            "Siemens S5 OB 251, Emerson E2 PID, Emerson DeltaV PID, CALC and stick-slip "
            "compensator)",
    PLANT: "Valve nonlinearity models, stiction compensation, relay auto-tuning and loop "
           "metrics: implementation reference",
}

SECTIONS: dict[str, dict[str, str]] = {
    VENDOR: {
        "0": "conventions: confidence tags and notation",
        "1": "GE PACSystems PID built-in function block (PID_IND and PID_ISA)",
        "1.1": "GE PID: function interface (operands SP, PV, MAN, UP, DN, enable, CV, ok)",
        "1.2": "GE PID: the 40-word reference array, word by word",
        "1.3": "GE PID: Config Word (word 13) bits, and the derivative change table",
        "1.4": "GE PID: Control Word (word 15) and Override",
        "1.5": "GE PID: integer scaling rules, integral remainder, rounding and word widths",
        "1.6": "GE PID: equations of PID_IND and PID_ISA, and the signal path",
        "1.7": "GE PID: per-solution algorithm in evaluation order (steps 1-14)",
        "1.8": "GE PID: timing and tuning guidance (sample period limits)",
        "1.9": "GE PID: worked examples G1-G15",
        "1.10": "GE PID: quirks an emulator must reproduce",
        "2": "Siemens SIMATIC S5 integrated PID control block (OB 251)",
        "2.1": "S5 PID: call convention (controller DB, OB 13 sampling time)",
        "2.2": "S5 PID: controller data block layout, parameter ranges, the ×0.001 = ÷1024 "
               "scaling",
        "2.3": "S5 PID: control bits in DR 11 (AUTO, XZ_EIN, REG_AUS, GESCHW, HANDART, NO_Z)",
        "2.4": "S5 PID: notation (XW, PW, QW, PZ, QZ, dZ)",
        "2.5": "S5 PID: correction-rate (velocity) law, its four variants and sign conventions",
        "2.6": "S5 PID: the derivative memory dD and its transcription ambiguity (law A)",
        "2.7": "S5 PID: positioning algorithm and the DW 48 accumulator",
        "2.8": "S5 PID: output limits and anti-windup (I-action suppressed at a limit)",
        "2.9": "S5 PID: manual mode (D 11.0 = 0)",
        "2.10": "S5 PID: controller off (REG_AUS) and the first call",
        "2.11": "S5 PID: timing (no clock: TA only from the OB 13 call rate)",
        "2.12": "S5 PID: the CPU 928B OB 250/251 floating-point variant and its differences",
        "2.13": "S5 PID: worked examples (PI step, D-element and ramp checks)",
        "2.14": "S5 PID: quirks an emulator must reproduce",
        "3": "Emerson E2 (RX/BX/CX) controller PID",
        "3.1": "E2 PID: the applications that use it",
        "3.2": "E2 PID: settings (throttling range, P/I/D mode gains, output at setpoint, "
               "clamps, MAE, update interval, filter, override)",
        "3.3": "E2 PID: the incremental (velocity) algorithm, P, I and D modes",
        "3.4": "E2 PID: output clamps and the throttling range shift",
        "3.5": "E2 PID: Minimum Accumulated Error (no I adjustment near the setpoint)",
        "3.6": "E2 PID: valve filtering (filter period and percentage)",
        "3.7": "E2 PID: cell chain, override and output stages (sequencer, PWM)",
        "3.8": "E2 PID: worked examples E1-E8",
        "3.9": "E2 PID: unknowns (D formula, I scaling, start-up output, defaults)",
        "4": "Emerson DeltaV standard PID function block",
        "4.1": "DeltaV PID: parameters (emulator subset), units, ranges and defaults",
        "4.2": "DeltaV PID: Standard and Series forms, reset by external positive feedback",
        "4.3": "DeltaV PID: STRUCTURE options (which terms act on error and which on PV)",
        "4.4": "DeltaV PID: reset, anti-reset windup (ARW window, RESET/16), dynamic reset "
               "limit, IDEADBAND, limit status",
        "4.5": "DeltaV PID: modes, tracking and bumpless transfer",
        "4.6": "DeltaV PID: status handling and the Fieldbus status byte encoding",
        "4.7": "DeltaV PID: per-scan order of the reference implementation (steps 1-11)",
        "4.8": "DeltaV PID: worked examples DV1-DV4",
        "4.9": "DeltaV PID: quirks",
        "5": "DeltaV relay autotuner (DeltaV Tune / InSight on-demand tuning)",
        "5.1": "DeltaV autotuner: procedure (relay test in LO mode) and identified quantities",
        "5.2": "DeltaV autotuner: equations for an emulator (relay analysis)",
        "6": "DeltaV CALC block and the stick-slip compensator",
        "6.1": "DeltaV CALC: expression semantics (syntax, parameter paths, .ST, float32, "
               "write/read visibility, execution order)",
        "6.2": "stick-slip compensator: its module parameters, defaults and labels",
        "6.3": "stick-slip compensator: the expression line by line",
        "6.4": "stick-slip compensator: the asymmetric noise-band thresholds",
        "6.5": "stick-slip compensator: who computes DITHER_OUT (the SGGN1 signal generator)",
        "6.6": "stick-slip compensator: the kicker as a relay with hysteresis",
        "6.7": "stick-slip compensator: units inconsistencies to reproduce, not fix",
        "6.8": "stick-slip compensator: golden step-through",
        "7": "cross-vendor differences an emulator must preserve (number format, form, time, "
             "error sign, limits, anti-windup, manual, status)",
        "8": "open questions before bit-exact claims (item 1 GE, 2 S5, 3 E2, 4 DeltaV PID, "
             "5 compensator)",
        "9": "references",
    },
    PLANT: {
        "1": "control-valve nonlinearity models",
        "1.1": "valve models: vocabulary of the valve phase plot (S, J, static and kinetic "
               "bands) and its physical meaning",
        "1.2": "valve models: Choudhury-Shah-Thornhill two-parameter (S, J) stiction model, "
               "step by step, with implementation notes",
        "1.3": "valve models: Kano et al. stiction model",
        "1.4": "valve models: He et al. two-layer (fs, fd) stiction model",
        "1.5": "valve models: deadband (backlash) and resolution (quantiser, resolution limit)",
        "1.6": "valve models: physical (Karnopp) friction model of a spring-diaphragm valve "
               "and its real-valve parameter set",
        "1.7": "valve models: mapping ISA / EnTech / McMillan terms (deadband, resolution) "
               "onto S and J",
        "1.8": "valve models: worked examples (OP ramps and short sequences, S = 3, J = 1)",
        "1.9": "valve models: describing function of the S/J model",
        "2": "stiction compensation",
        "2.1": "stiction compensation: common architecture (correction added to the "
               "controller output)",
        "2.2": "stiction compensation: dither",
        "2.3": "stiction compensation: the DeltaV dither + kicker compensator",
        "2.4": "stiction compensation: the knocker (Hägglund 2002)",
        "2.5": "stiction compensation: two-move compensation (Srinivasan & Rengaswamy)",
        "2.6": "stiction compensation: constant reinforcement (Ivan & Lakshminarayanan)",
        "2.7": "stiction compensation: other options",
        "2.8": "stiction compensation: reproducible comparison of the compensators on a "
               "FOPDT loop (PV σ, travel, reversals)",
        "3": "relay feedback auto-tuning",
        "3.1": "relay tuning: the basic relay experiment (Åström & Hägglund 1984)",
        "3.2": "relay tuning: exact relay oscillation on FOPDT and integrating plants",
        "3.3": "relay tuning: biased (asymmetric) relay for static gain, dead time and time "
               "constant",
        "3.4": "relay tuning: practical procedure and defaults (hysteresis, amplitude, "
               "convergence, abort rules, load disturbances)",
        "3.5": "relay tuning: PID forms (ideal, parallel, series) and their conversions",
        "3.6": "relay tuning: tuning rules (ultimate-point and FOPDT rules, SIMC, AMIGO)",
        "4": "loop performance metrics",
        "4.1": "loop metrics: definitions (IAE, overshoot, variability, valve travel, "
               "reversals)",
        "4.2": "loop metrics: oscillation detection",
        "4.3": "loop metrics: stiction and nonlinearity detection indices",
        "5": "reference results a simulation can be checked against",
        "5.1": "reference results: stiction limit cycles, describing function vs simulation",
        "5.2": "reference results: other oracles in the document",
        "5.3": "reference results: ISA-75.25.01 / ISA-TR75.25.02 valve response tests",
        "5.4": "reference results: open-source implementations",
        "6": "recommendations for the project, an implementation checklist (item 1 valve "
             "models, 2 unit tests, 3 loop simulator, 4 relay tuner, 5 compensators, "
             "6 loop assessment)",
        "7": "gaps and uncertainties",
        "8": "references",
    },
}

REFERENCES: dict[str, str] = {
    # GE PACSystems / VersaMax / Series 90-30
    "R1": "GE, PACSystems RX7i, RX3i and RSTi-EP CPU Programmer's Reference Manual, "
          "GFK-2950C: PID reference array, words 1-6 (p. 362)",
    "R2": "GE, GFK-2950C: PID operands and overview (pp. 360-361)",
    "R3": "GE, GFK-2950C: PID Manual Command and modes (pp. 369, 373)",
    "R4": "GE, GFK-2950C: PID algorithm selection, PID_IND and PID_ISA equations, Figure 16 "
          "(p. 370); PID example 7.7 (p. 378); tuning (p. 375)",
    "R5": "GE, GFK-2950 (PACSystems RSTi-EP copy): Config Word, reference array words 7-13 "
          "(pp. 367, 374)",
    "R6": "GE, GFK-2950: timing, sample period, dead band, SVC_REQ remark (pp. 364, 366, 372)",
    "R7": "GE, GFK-2950: slew-time examples (p. 365)",
    "R8": "GE, GFK-2950 (general; the same manual family as R1-R7)",
    "R9": "GE, VersaMax PLC User Manual, GFK-1503: PID (pp. 278, 280)",
    "R10": "GE, Series 90-30/20/Micro manual, GFK-0467K: Table 4-4",
    "R11": "GE, Series 90-30/20/Micro manual: PID (p. 258)",
    "R12": "third-party article on GE PACSystems PID troubleshooting: configuration bits "
           "(anti-reset windup bit 4, clamps), industrialmonitordirect.com",
    "R13": "seed 003: vendor excerpt on the GE PACSystems PID derivative and error modes",
    # Siemens S5
    "R20": "Siemens, SIMATIC S5-100U system manual, EWA 4NEB 812 6120-02b, chapter 9, "
           "integrated PID: legend, initialisation and sampling, example (pp. 246, 251, 252)",
    "R21": "Siemens, SIMATIC S5-100U system manual (p. 250)",
    "R22": "Siemens, SIMATIC S5-100U system manual, German edition: control-bit table 9.7 "
           "(p. 249)",
    "R23": "Siemens, SIMATIC S5-115U manual, German edition: OB 251 (p. 342)",
    "R24": "Siemens, SIMATIC S5-115F manual: OB 251 (pp. 216-220)",
    "R25": "Siemens, SIMATIC S5-95F manual: OB 251 and the OB 13 interval (pp. 257, 260)",
    "R26": "Siemens, SIMATIC S5-115U manual: controller DB layout and the 1/1024 note (p. 411)",
    "R27": "Siemens, CPU 928B programming guide: OB 250/251 floating-point PID "
           "(pp. 362-373)",
    "R28": "seed 002: S5-100U manual page 9-18, the velocity law of OB 251",
    # Emerson E2
    "R30": "Emerson (CPC), E2 RX/BX/CX Installation and Operation Manual 026-1610, "
           "Appendix D \"PID Control\" (pp. D-2 to D-5)",
    "R31": "Emerson (CPC), E2 manual 026-1610: Loop/Sequence Control application and PID "
           "cells",
    "R32": "Emerson (CPC), E2 manual 026-1610 (another copy, p. 179)",
    "R33": "field defaults of the EEPR PID settings, hvac-talk.com forum thread "
           "\"Question about EEPR settings on CPC\"",
    "R34": "seed 001: excerpt of the E2 manual 026-1610 (output limits, Minimum Accumulated "
           "Error, filtering)",
    # Emerson DeltaV
    "R40": "Emerson, DeltaV Books Online (control studio): PID function block execution",
    "R41": "Emerson, DeltaV Books Online (function block reference): PID function block "
           "execution",
    "R42": "Emerson, DeltaV Books Online: PID function block parameters",
    "R43": "Emerson, DeltaV Books Online: PID function block status handling",
    "R44": "Emerson, DeltaV Books Online: function block status options",
    "R45": "Emerson, DeltaV Books Online (I/O configuration): function block status",
    "R46": "Emerson, DeltaV Books Online: PID function block specifications",
    "R47": "Emerson, DeltaV Books Online (operator displays): PID function block detail "
           "display",
    "R48": "Emerson, DeltaV Books Online: DeltaV InSight and DeltaV Tune",
    "R49": "Emerson, DeltaV Books Online (batch tutorial): expression syntax rules; using the "
           "expression editor",
    "R50": "Emerson, DeltaV Books Online: Calc/Logic function block execution",
    "R51": "Emerson, DeltaV Books Online: internal reference parameters of function blocks",
    "R52": "Emerson, DeltaV Books Online 10.3: Using DeltaV Tune",
    "R53": "Proportional-Integral-Derivative (PID) function block reference (an Emerson "
           "document, docsbay.net copy)",
    "R54": "Emerson Automation Experts (2020): How PID loop dynamic reset limit works",
    "R55": "Emerson Automation Experts (2008): advanced PID functions",
    "R56": "G. McMillan, Modeling and Control (2006): PID design",
    "R57": "Emerson, Rosemount OCX8800 manual: Foundation Fieldbus PID block (STRUCTURE list, "
           "fixed derivative filter) (pp. 167, 168, 180)",
    "R58": "Emerson, Fisher FIELDVUE DVC6000f, DVC6200f and DLC3020f manuals: Foundation "
           "Fieldbus PID block and tuner parameters",
    "R59": "G. McMillan, \"Getting a kick out of stick-slip\", Modeling and Control "
           "(December 2006)",
    "R60": "seed 000: the DeltaV stick-slip compensator module (CALC expression and "
           "parameters)",
    "R61": "Emerson, DeltaV Books Online: parameter data types",
}

SEEDS: dict[str, str] = {
    "000": "vendor excerpt the specifications were written from: the DeltaV stick-slip "
           "compensator (dither + kicker) module, its CALC expression and parameter list "
           "(vendor-blocks R60)",
    "001": "vendor excerpt the specifications were written from: the Emerson E2 manual "
           "026-1610 on output limits, Minimum Accumulated Error and output filtering "
           "(vendor-blocks R34)",
    "002": "vendor excerpt the specifications were written from: the Siemens S5-100U manual "
           "page 9-18, the velocity law of OB 251 (vendor-blocks R28)",
    "003": "vendor excerpt the specifications were written from: the GE PACSystems PID "
           "derivative and error modes (vendor-blocks R13)",
}

TAGS: dict[str, dict[str, str]] = {
    VENDOR: {
        "V": "stated in the vendor's documentation (the spec cites the source)",
        "D": "derived by the spec from vendor-documented material; the arithmetic is "
             "reproducible",
        "A": "an assumption, or an emulator design choice where the vendor text is silent; "
             "each is an option of the block",
        "?": "unknown: not settled by the sources retrieved; the block's choice is an option "
             "and may differ from the real controller",
    },
    PLANT: {
        "V": "checked numerically by the spec's author (re-implementation, fine-step "
             "simulation or symbolic integration)",
        "S": "taken from a public source file or document the spec names",
        "L": "a value or statement from the primary paper or book, whose full text was not "
             "available: very likely right, not verified",
        "I": "the spec's own interpretation or inference, not a published statement",
    },
}

PROJECT_TAGS: dict[str, str] = {
    "loopworks design": "a choice of loopworks itself, not taken from a specification or a "
                        "vendor",
    "practice": "common industrial practice, not from a single source",
}

def kind_document(module: str) -> str:
    """The document a bare "spec X.Y" means on the page of a kind defined in ``module``: the
    vendor specification for the vendors' blocks (``loopworks.vendors.*``), plant-and-tuning
    for every other kind (the generic pid, compensators, relay, plant)."""
    return VENDOR if module.startswith("loopworks.vendors.") else PLANT
