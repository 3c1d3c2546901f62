"""Compare glowref.exe output for NCAR's example input (in.basic.aur) with the
reference output out.basic.aur shipped in the GLOW distribution."""
import sys, io, csv
import numpy as np
ref_path, new_path = sys.argv[1], sys.argv[2]
lines = open(ref_path).read().splitlines()
i1 = [i for i,l in enumerate(lines) if l.strip().startswith('Z     Tn')][0]
i2 = [i for i,l in enumerate(lines) if l.strip().startswith('Z      3371')][0]
t1 = np.array([[float(x) for x in l.split()] for l in lines[i1+1:i2]])
t2 = np.array([[float(x) for x in l.split()] for l in lines[i2+1:i2+1+len(t1)]])
rows = [l for l in open(new_path).read().splitlines() if not l.startswith('#')]
rd = list(csv.DictReader(io.StringIO('\n'.join(rows))))
col = lambda k: np.array([float(r[k]) for r in rd])
z = col('altitude_km'); assert np.allclose(z, t1[:,0])
checks1 = [('Tn',1,'Tn_K'),('O',2,'O_cm3'),('N2',3,'N2_cm3'),('NO',4,'NO_cm3'),('Ne(in)',5,'ne_apriori_iri_cm3'),
           ('Ne(out)',6,'ne_cm3'),('Ionrate',7,'ion_rate_total_cm3s'),('O+',8,'Op4S_cm3'),('O2+',9,'O2p_cm3'),
           ('NO+',10,'NOp_cm3'),('N(2D)',11,'N2D_cm3')]
names2 = ['3371','4278','5200','5577','6300','7320','10400','3466','7774','8446','3726','LBH','1356','1493','1304']
keys2 = ['ver_3371','ver_4278','ver_5200','ver_5577','ver_6300','ver_7320','ver_10400','ver_3466','ver_7774','ver_8446','ver_3726','ver_LBH','ver_1356','ver_1493','ver_1304']
print('quantity  max|rel diff| where ref>tiny   (ref printed to 3 significant digits / 2 decimals)')
for name, ic, key in checks1:
    r = t1[:,ic]; n = col(key); m = np.abs(r) > 1e-30
    rel = np.abs(n[m]-r[m])/np.abs(r[m])
    print(f'{name:8s} {rel.max():.3e}  median {np.median(rel):.2e}')
for ic,(name,key) in enumerate(zip(names2,keys2)):
    r = t2[:,ic+1]; n = col(key); m = r >= 1.0   # 2-decimal print; compare where >= 1
    rel = np.abs(n[m]-r[m])/r[m]
    colref = np.sum(r*np.gradient(z)); colnew = np.sum(n*np.gradient(z))
    print(f'{name:8s} {rel.max() if m.any() else float("nan"):.3e}  n={m.sum():3d}  column ratio new/ref {colnew/colref:.5f}')
