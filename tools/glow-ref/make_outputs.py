"""Split glowref.exe output into per-case CSVs and write summary.txt.
Usage: python3 make_outputs.py build/glowref_cases.out OUTDIR [NOTE]
NOTE (optional) is written under the case line, e.g. how the build differs from stock."""
import sys, io, csv, re
import numpy as np

src, outdir = sys.argv[1], sys.argv[2]
note = sys.argv[3] if len(sys.argv) > 3 else None
blocks = [b for b in open(src).read().split('# end\n') if b.strip()]

def parabolic_peak(z, y):
    k = int(np.argmax(y))
    if k == 0 or k == len(y) - 1:
        return z[k]
    zz, yy = z[k-1:k+2], y[k-1:k+2]
    a, b, c = np.polyfit(zz, yy, 2)
    return -b / (2 * a) if a < 0 else z[k]

summ = []
for b in blocks:
    lines = b.splitlines()
    meta = [l for l in lines if l.startswith('#')]
    body = [l for l in lines if not l.startswith('#')]
    ec = float(re.search(r'ec_eV=\s*([0-9.]+)', meta[1]).group(1))
    ef = float(re.search(r'ef_erg_cm2_s=\s*([0-9.]+)', meta[1]).group(1))
    vcb = [float(x) for x in meta[3].split('=')[1].split()]
    efrac = float(re.search(r'efrac=\s*(\S+)', meta[2]).group(1))
    sza = float(re.search(r'sza_deg=\s*(\S+)', meta[2]).group(1))
    inputs = meta[1].lstrip('# ').split(' ef_erg')[0]
    fn = f'{outdir}/glow_E{ec/1000:g}keV.csv' if ef > 0.001 else f'{outdir}/glow_noprecip.csv'
    with open(fn, 'w') as f:
        for m in meta:
            f.write(m + '\n')
        f.write('# units: ver_* and ver*_s* photons cm-3 s-1; pO1D_*, prod_*, ion_rate_*, eion_* cm-3 s-1; loss_* s-1; densities cm-3; T K\n')
        f.write('# ver_3914_derived = (B37/B38=0.65/0.20) x electron-impact+photoionization 4278 terms (not a GLOW output); '
                'ver_6364_derived = A(6364)/A(6300) x ver_6300\n')
        f.write('\n'.join(l.replace(' ', '') for l in body) + '\n')
    rd = list(csv.DictReader(io.StringIO('\n'.join(body))))
    col = lambda k: np.array([float(r[k]) for r in rd])
    z = col('altitude_km')
    res = {'E0_keV': ec/1000, 'ef': ef, 'efrac': efrac, 'sza': sza, 'inputs': inputs}
    for key, iw in [('4278', 1), ('5577', 3), ('6300', 4), ('3914_derived', None)]:
        y = col('ver_' + key)
        res['col_trapz_' + key] = np.trapezoid(y, z * 1e5)
        res['col_glow_' + key] = vcb[iw] * 1e6 if iw is not None else np.nan
        res['peak_grid_' + key] = z[int(np.argmax(y))]
        res['peak_parab_' + key] = parabolic_peak(z, y)
    y = col('ion_rate_eimpact_cm3s'); res['peak_grid_eion'] = z[int(np.argmax(y))]
    res['col_eion'] = np.trapezoid(y, z * 1e5)
    # O(1D) production column breakdown
    srcs = [k for k in rd[0] if k.startswith('pO1D_s')]
    tot = sum(np.trapezoid(col(k), z*1e5) for k in srcs)
    res['o1d_frac'] = {k: np.trapezoid(col(k), z*1e5) / tot for k in srcs}
    if ef <= 0.001:
        bg = res
        continue
    summ.append(res)

with open(f'{outdir}/summary.txt', 'w') as f:
    f.write('GLOW v0.981 reference runs (driver glowref.f90, sources from PyPI glowpython-4.0.4 src/GLOW)\n')
    f.write('Case: %s,\n' % ' '.join(summ[0]['inputs'].split()))
    f.write('      Maxwellian (maxt, itail=0), ef=1 erg cm-2 s-1, ec=E0; sza=%.1f deg (>105, EPHOTO not called; QBACK night background ionization IS included)\n' % summ[0]['sza'])
    if note:
        f.write('Build: %s\n' % note)
    f.write('Columns: trapezoid integral of the volume emission rate over the 102-level GLOW grid (80-640 km), photons cm-2 s-1 (= R x 1e6);\n')
    f.write('         GLOW_vcb = GLOW\'s own vertical column brightness (centred-difference dz sum, gchem.f90) x 1e6.\n')
    f.write('Peak altitude: grid point of maximum VER (grid spacing 1 km for 80-110 km, 1.5-2 km to 134 km, 3-10 km above), and a 3-point parabolic refinement.\n\n')
    for r in summ:
        f.write(f"E0 = {r['E0_keV']:g} keV   (GLOW energy-conservation efrac = {r['efrac']:.4f})\n")
        for key in ['4278', '5577', '6300', '3914_derived']:
            f.write(f"  {key:13s} column trapz = {r['col_trapz_'+key]:.4e} cm-2 s-1 ({r['col_trapz_'+key]/1e6:8.2f} R)"
                    + (f"   GLOW_vcb = {r['col_glow_'+key]:.4e}" if not np.isnan(r['col_glow_'+key]) else '')
                    + f"   peak: grid {r['peak_grid_'+key]:6.1f} km, parabolic {r['peak_parab_'+key]:6.1f} km\n")
        c4 = r['col_trapz_4278']
        f.write(f"  ratio 6300/4278 = {r['col_trapz_6300']/c4:.4f}   ratio 5577/4278 = {r['col_trapz_5577']/c4:.4f}"
                f"   (from GLOW_vcb: {r['col_glow_6300']/r['col_glow_4278']:.4f}, {r['col_glow_5577']/r['col_glow_4278']:.4f})\n")
        f.write(f"  4278 column per erg cm-2 s-1 = {c4/r['ef']:.4e} photons cm-2 s-1 ({c4/r['ef']/1e6:.2f} R per erg cm-2 s-1)\n")
        f.write(f"  electron-impact ionization: column {r['col_eion']:.4e} cm-2 s-1, peak (grid) {r['peak_grid_eion']:.1f} km;"
                f" 4278 photons per ion pair = {c4/r['col_eion']:.4f}\n")
        f.write("  O(1D) production column fractions: " + ', '.join(f"{k[5:]}={v:.3f}" for k, v in r['o1d_frac'].items() if v > 5e-4) + "\n\n")
    f.write('No-precipitation run (same atmosphere/ionosphere, ef=0; written to glow_noprecip.csv): GLOW nightglow background\n')
    for key in ['4278', '5577', '6300']:
        f.write(f"  {key}: column trapz = {bg['col_trapz_'+key]:.4e} cm-2 s-1 ({bg['col_trapz_'+key]/1e6:.2f} R), peak (grid) {bg['peak_grid_'+key]:.1f} km\n")
    f.write('  Columns above INCLUDE this background (they are full GLOW outputs). Difference (run - noprecip), photons cm-2 s-1:\n')
    for r in summ:
        d = {k: r['col_trapz_'+k] - bg['col_trapz_'+k] for k in ['4278', '5577', '6300']}
        f.write(f"  E0={r['E0_keV']:g} keV: 4278 {d['4278']:.4e}, 5577 {d['5577']:.4e}, 6300 {d['6300']:.4e};"
                f" ratios 6300/4278 {d['6300']/d['4278']:.4f}, 5577/4278 {d['5577']/d['4278']:.4f}\n")
    f.write('  (a difference is only indicative: precipitation changes Ne, hence the recombination terms, nonlinearly)\n\n')
    f.write('Table (trapz columns, photons cm-2 s-1):\n')
    f.write('E0_keV, col_4278, col_5577, col_6300, ratio_6300_4278, ratio_5577_4278, peak_4278_km, peak_5577_km, peak_6300_km, col_4278_per_erg\n')
    for r in summ:
        c4 = r['col_trapz_4278']
        f.write(f"{r['E0_keV']:g}, {c4:.4e}, {r['col_trapz_5577']:.4e}, {r['col_trapz_6300']:.4e}, {r['col_trapz_6300']/c4:.4f}, "
                f"{r['col_trapz_5577']/c4:.4f}, {r['peak_grid_4278']:.1f}, {r['peak_grid_5577']:.1f}, {r['peak_grid_6300']:.1f}, {c4/r['ef']:.4e}\n")
print(open(f'{outdir}/summary.txt').read())
