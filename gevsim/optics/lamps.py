"""The names of the lamp spectra :func:`gevsim.optics.lamp_spectrum` knows, without importing colour-science.

Checking a scene's ``spectrum = "FL2"`` imported colour-science (a second, matplotlib with it) where listing
the scenes reads nothing else (issue 37, item 5). A name here is one of colour-science's own keys, exactly;
any other (another spelling colour accepts, such as ``"fl2"``, or an unknown name) goes to
:func:`~gevsim.optics.lamp_spectrum`, which answers as before. ``tests/test_startup.py`` checks that these
are colour-science's keys.
"""

#: ``colour.SDS_ILLUMINANTS`` then ``colour.SDS_LIGHT_SOURCES`` keys (colour-science 0.4.7).
LAMP_NAMES: frozenset[str] = frozenset((
    "A", "B", "C", "D50", "D55", "D60", "D65", "D75", "E", "FL1", "FL2", "FL3", "FL4", "FL5", "FL6", "FL7", "FL8",
    "FL9", "FL10", "FL11", "FL12", "FL3.1", "FL3.2", "FL3.3", "FL3.4", "FL3.5", "FL3.6", "FL3.7", "FL3.8", "FL3.9",
    "FL3.10", "FL3.11", "FL3.12", "FL3.13", "FL3.14", "FL3.15", "HP1", "HP2", "HP3", "HP4", "HP5", "LED-B1",
    "LED-B2", "LED-B3", "LED-B4", "LED-B5", "LED-BH1", "LED-RGB1", "LED-V1", "LED-V2", "ID65", "ID50",
    "ISO 7589 Photographic Daylight", "ISO 7589 Sensitometric Daylight", "ISO 7589 Studio Tungsten",
    "ISO 7589 Sensitometric Studio Tungsten", "ISO 7589 Photoflood", "ISO 7589 Sensitometric Photoflood",
    "ISO 7589 Sensitometric Printer",
    "Natural", "Philips TL-84", "SA", "SC", "T8 Luxline Plus White", "T8 Polylux 3000", "T8 Polylux 4000",
    "Thorn Kolor-rite", "Cool White FL", "Daylight FL", "HPS", "Incandescent", "LPS", "Mercury", "Metal Halide",
    "Neodimium Incandescent", "Super HPS", "Triphosphor FL", "3-LED-1 (457/540/605)", "3-LED-2 (473/545/616)",
    "3-LED-2 Yellow", "3-LED-3 (465/546/614)", "3-LED-4 (455/547/623)", "4-LED No Yellow", "4-LED Yellow",
    "4-LED-1 (461/526/576/624)", "4-LED-2 (447/512/573/627)", "Luxeon WW 2880", "PHOS-1", "PHOS-2", "PHOS-3",
    "PHOS-4", "Phosphor LED YAG", "60 A/W (Soft White)", "C100S54 (HPS)", "C100S54C (HPS)",
    "F32T8/TL830 (Triphosphor)", "F32T8/TL835 (Triphosphor)", "F32T8/TL841 (Triphosphor)",
    "F32T8/TL850 (Triphosphor)", "F32T8/TL865/PLUS (Triphosphor)", "F34/CW/RS/EW (Cool White FL)",
    "F34T12/LW/RS/EW", "F34T12WW/RS/EW (Warm White FL)", "F40/C50 (Broadband FL)", "F40/C75 (Broadband FL)",
    "F40/CWX (Broadband FL)", "F40/DX (Broadband FL)", "F40/DXTP (Delux FL)", "F40/N (Natural FL)",
    "H38HT-100 (Mercury)", "H38JA-100/DX (Mercury DX)", "MHC100/U/MP/3K", "MHC100/U/MP/4K",
    "SDW-T 100W/LV (Super HPS)", "Kinoton 75P",
))
