"""A 1-D estimate of the paper mode's colours by altitude, for choosing its
constants before rendering: one vertical fall per §2.4.1 with exact free paths (the
collision density at z is sigma n(z) P(Poisson(sigma N(z)) < budget), N the column above),
§2.4.2's species choice by density and line shares, and quenching either by eq 2.25 with
the fall's radius (today's paper mode) or by the measured rate coefficients of
shared/aurora-physics.md (eq 2.25 made exact per quencher). The curtain is where the
luminance is >= 2 % of its peak, cut into thirds by altitude, as the image tests cut rows.
CIE 1931 colour matching values at the five lines (approximate), linear sRGB.
Run: python3 tools/paper-look/model.py   (reads crates/aurora/data/atmosphere_msis21.csv)
Measured 2026-12-03 (see the note): with measured quenching the top third is not
redder than the middle for Table 3.2's fixed 100-collision budget.
"""
import csv, math
rows=[r for r in csv.DictReader(open('crates/aurora/data/atmosphere_msis21.csv'))]
z=[float(r['altitude_km']) for r in rows]; nO=[float(r['n_o']) for r in rows]; nN2=[float(r['n_n2']) for r in rows]; nO2=[float(r['n_o2']) for r in rows]; T=[float(r['temperature_k']) for r in rows]
# fine grid 0.25 km, log-linear
def interp(a,x):
    i=min(int(x-z[0]),len(z)-2); t=x-z[0]-i
    return math.exp(math.log(a[i])*(1-t)+math.log(a[i+1])*t)
def interpT(x):
    i=min(int(x-z[0]),len(z)-2); t=x-z[0]-i; return T[i]*(1-t)+T[i+1]*t
r=4e-11; sig=math.pi*r*r
dz=0.25; top=300.0
alts=[top-k*dz for k in range(int((top-85)/dz))]
# cmf approx CIE1931 at lines: (x,y,z)
cmf={557.7:(0.5575,0.9978,0.0047),630.0:(0.6424,0.265,0.00005),391.4:(0.0055,0.00016,0.026),427.8:(0.25,0.0103,1.22),670.5:(0.087,0.032,0.0)}
def srgb(X,Y,Z):
    return (3.2406*X-1.5372*Y-0.4986*Z, -0.9689*X+1.8758*Y+0.0415*Z, 0.0557*X-0.2040*Y+1.0570*Z)
kB=1.380649e-23; Da=1.66054e-27
def vmean(Tk,m): return math.sqrt(8*kB*Tk/(math.pi*m*Da))
def poisson_cdf_lt(lam,k):
    # P(Poisson(lam) < k)
    s=0.0; term=math.exp(-lam); 
    for i in range(k):
        s+=term; term*=lam/(i+1)
    return s
def run(quench, yields, label, budgets=((100, 1.0),)):
    """Print the curtain's thirds for falls whose collision budgets are `budgets`
    ((collisions, weight) pairs, weights summing to 1)."""
    N=0.0; prof=[]
    for a in alts:
        o,n2,o2,t=interp(nO,a),interp(nN2,a),interp(nO2,a),interpT(a)
        tot=o+n2+o2
        alive=sum(w*poisson_cdf_lt(sig*N,k) for k,w in budgets)
        coll=sig*tot*dz*1e3*alive  # collisions in this slab
        N+=tot*dz*1e3
        pO,pN=o/tot,n2/tot
        s557,s630=quench(o,n2,o2,t,tot)
        em={557.7:pO*yields['g']*s557,630.0:pO*yields['r']*s630,391.4:pN*yields['n'][0],427.8:pN*yields['n'][1],670.5:pN*yields['n'][2]}
        X=sum(coll*em[l]*cmf[l][0] for l in em);Y=sum(coll*em[l]*cmf[l][1] for l in em);Z=sum(coll*em[l]*cmf[l][2] for l in em)
        prof.append((a,srgb(X,Y,Z),Y))
    ymax=max(p[2] for p in prof)
    lit=[p for p in prof if p[2]>=0.02*ymax]
    hi,lo=lit[0][0],lit[-1][0]
    span=hi-lo
    def band(f0,f1):
        R=G=B=0
        for a,(rr,gg,bb),y in lit:
            f=(hi-a)/span
            if f0<=f<f1: R+=rr;G+=gg;B+=bb
        return R,G,B
    top3,mid3=band(0,1/3),band(1/3,2/3)
    peak=max(prof,key=lambda p:p[2])[0]
    mag=[a for a,(rr,gg,bb),y in lit if rr>gg and bb>gg]
    print(f"{label}: lit {lo:.0f}-{hi:.0f} km, lum peak {peak:.0f}; top R/G {top3[0]/top3[1]:.3f} mid R/G {mid3[0]/mid3[1]:.3f} ratio {(top3[0]/top3[1])/(mid3[0]/mid3[1]):.2f}; mid RGB {tuple(round(x/max(mid3),2) for x in mid3)}; magenta alts {min(mag) if mag else None}-{max(mag) if mag else None}")
def hard(o,n2,o2,t,tot):
    surv=lambda tau,m: math.exp(-math.sqrt(2)*tot*sig*vmean(t,m)*tau)
    return surv(0.74,16),surv(110,16)
def measured(o,n2,o2,t,tot):
    c=1e-6 # cm3->m3
    k1s=2.0e-14*o+4.0e-12*math.exp(-865/t)*o2
    k1d=2.0e-11*math.exp(107.8/t)*n2+2.9e-11*math.exp(67.5/t)*o2+3.0e-12*o
    A1s=1.06+0.045; A1d=0.00585+0.00185
    return math.exp(-k1s*c/A1s), math.exp(-k1d*c/A1d)
thesis={'g':0.5,'r':0.5,'n':(0.65,0.20,0.15)}
run(hard,thesis,"today (hard sphere r, g .5)")
run(measured,thesis,"measured k, g .5")
run(measured,{'g':0.9,'r':0.1,'n':(0.65,0.2,0.15)},"measured k, g .9")
ipc=100/35
run(measured,{'g':1.0,'r':1.0,'n':(0.07*ipc,0.07/3.25*ipc,0.014*ipc)},"measured, O all, N2 phys yields")

def maxwellian_budgets(E0):
    """Budgets k with weight k exp(-k/E0) (a Maxwellian number flux), mean 2 E0."""
    ks=range(1,1000); w=[k*math.exp(-k/E0) for k in ks]; W=sum(w)
    return [(k,x/W) for k,x in zip(ks,w) if x/W>1e-12]
for E0 in (50,20,10):
    run(measured,{'g':0.5,'r':0.5,'n':(0.65,0.2,0.15)},f"measured, Maxwellian budgets E0={E0}",maxwellian_budgets(E0))
    run(measured,{'g':0.9,'r':0.1,'n':(0.65,0.2,0.15)},f"measured g.9, Maxwellian budgets E0={E0}",maxwellian_budgets(E0))
