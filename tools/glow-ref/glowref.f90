program glowref

! Reference-profile driver for the GLOW model (v0.981 physics, as packaged in
! the PyPI sdist glowpython-4.0.4, src/GLOW/).  Written for the phenomena
! project.  It reproduces the set-up of NCAR GLOW v0.981 glowbasic.f90:
!   iscale=1 (EUVAC), xuvfac=3, kchem=4, jlocal=0, itail=0 (pure Maxwellian),
!   nbins=190 (energy grid to ~50 keV), jmax=102 with the 80-640 km altitude grid
!   of NCAR v0.98/v0.981 mzgrid.f90, IRI-90 switches jf(:)=.true., jf(5)=.false.
! and prints one CSV row per altitude with emission rates and the component
! production terms, instead of glowbasic's fixed-format table.
!
! Standard input, one case per line (same order as glowbasic):
!   idate ut glat glong f107a f107 f107p ap ef ec
! ef: total energy flux, erg cm-2 s-1; ec: characteristic energy E0, eV.
! Output: for each case a header block starting with '#' and a CSV table.

  use cglow,only: jmax,nbins,nex,nw,nc,nmaj
  use cglow,only: idate,ut,glat,glong,f107a,f107,f107p,ap,ef,ec
  use cglow,only: iscale,jlocal,kchem,xuvfac
  use cglow,only: sza,dip,efrac,ierr,vcb
  use cglow,only: zz,zo,zn2,zo2,zns,znd,zno,ztn,ze,zti,zte
  use cglow,only: ener,edel,phitop,sion,aglw,tei,tpi,tir,ecalc,zxden,zeta,zceta
  use cglow,only: production,loss
  use cglow,only: cglow_init, data_dir

  implicit none

  character(len=1024) :: iri90_dir, datadir_in
  real :: z(102), zun(102), zvn(102), oarr(30)
  integer :: jfin(12)
  real :: stl, fmono, emono, r3914
  integer :: j, ii, itail, instance, iostatus, ic

  real, parameter :: zgrid(102) = (/ &
          80.,  81.,  82.,  83.,  84.,  85.,  86.,  87.,  88.,  89., &
          90.,  91.,  92.,  93.,  94.,  95.,  96.,  97.,  98.,  99., &
         100., 101., 102., 103., 104., 105., 106., 107., 108., 109., &
         110.,111.5, 113.,114.5, 116., 118., 120., 122., 124., 126., &
         128., 130., 132., 134., 137., 140., 144., 148., 153., 158., &
         164., 170., 176., 183., 190., 197., 205., 213., 221., 229., &
         237., 245., 254., 263., 272., 281., 290., 300., 310., 320., &
         330., 340., 350., 360., 370., 380., 390., 400., 410., 420., &
         430., 440., 450., 460., 470., 480., 490., 500., 510., 520., &
         530., 540., 550., 560., 570., 580., 590., 600., 610., 620., &
         630., 640. /)

! Data directory: first command-line argument (must end with '/'), default 'data/'
  if (command_argument_count() >= 1) then
    call get_command_argument(1, datadir_in)
  else
    datadir_in = 'data/'
  endif
  data_dir  = trim(datadir_in)
  iri90_dir = trim(datadir_in)//'iri90/'

! Standard switches (as glowbasic v0.981):
  iscale = 1
  xuvfac = 3.
  kchem  = 4
  jlocal = 0
  itail  = 0
  fmono  = 0.
  emono  = 0.

  jmax  = 102
  nbins = 190
  z(:) = zgrid(:)

! Allocates arrays, reads solar-flux / photo cross-section / NOEM files,
! builds energy grid (egrid) and electron-impact cross sections (exsect):
  call cglow_init

! B(37)/B(38) of gchem.f90: N2+ 1NG (0,0) 3914 vs (0,1) 4278 branching (0.65/0.20)
  r3914 = 0.65 / 0.20

  do instance = 1, 10000
    read(5,*,iostat=iostatus) idate,ut,glat,glong,f107a,f107,f107p,ap,ef,ec
    if (iostatus /= 0) exit

    stl = ut/3600. + glong/15.
    if (stl < 0.) stl = stl + 24.
    if (stl >= 24.) stl = stl - 24.

    zz(:) = z(:) * 1.e5
    jfin(:) = 1
    jfin(5) = 0          ! as NCAR mzgrid: jf(5)=.false. (URSI foF2 coefficients)
    oarr(:) = 0.

    call mzgrid (jmax,nex,idate,ut,glat,glong,stl,f107a,f107,f107p,ap,z, &
                 jfin, oarr, iri90_dir, &
                 zo,zo2,zn2,zns,znd,zno,ztn,zun,zvn,ze,zti,zte,zxden)

    phitop(:) = 0.
    if (ef > .001 .and. ec > 1.) call maxt (ef,ec,ener,edel,nbins,itail,fmono,emono,phitop)

    call glow

    write(6,'(a)') '# GLOW v0.981 (glowpython-4.0.4 src/GLOW) via driver glowref.f90'
    write(6,'(a,i8,a,f8.1,a,f7.2,a,f8.2,a,f7.1,a,f7.1,a,f7.1,a,f6.1,a,f8.3,a,f9.1)') &
      '# idate=',idate,' ut_s=',ut,' glat=',glat,' glong=',glong,' f107a=',f107a, &
      ' f107=',f107,' f107p=',f107p,' ap=',ap,' ef_erg_cm2_s=',ef,' ec_eV=',ec
    write(6,'(a,f8.3,a,f8.3,a,es12.4,a,i3,a,f7.3)') '# sza_deg=',sza*180./3.1415926536, &
      ' dip_deg=',dip*180./3.1415926536,' efrac=',efrac,' ierr=',ierr,' stl_h=',stl
    write(6,'(a,15es12.4)') '# vcb_R(1:15)=',(vcb(ii),ii=1,nw)
    write(6,'(a,es12.4)') '# max_energy_bin_eV=',ener(nbins)

    write(6,'(a)') 'altitude_km,ver_4278,ver_5577,ver_6300,ver_3914_derived,' // &
      'ver_3371,ver_5200,ver_6364_derived,ver_7320,ver_10400,ver_3466,ver_7774,ver_8446,ver_3726,ver_LBH,' // &
      'ver_1356,ver_1493,ver_1304,' // &
      'ver6300_s01_eimpact_O,ver6300_s02_thermal_e_O,ver6300_s03_dissrec_O2p,ver6300_s04_N2D_O2,' // &
      'ver6300_s05_N2D_O,ver6300_s06_Np_O2,ver6300_s07_Op2D_O,ver6300_s08_eimpact_dissoc_O2,' // &
      'ver6300_s09_photodissoc_O2,ver6300_s10_O1S_cascade,' // &
      'pO1D_s01_eimpact_O,pO1D_s02_thermal_e_O,pO1D_s03_dissrec_O2p,pO1D_s04_N2D_O2,' // &
      'pO1D_s05_N2D_O,pO1D_s06_Np_O2,pO1D_s07_Op2D_O,pO1D_s08_eimpact_dissoc_O2,' // &
      'pO1D_s09_photodissoc_O2,pO1D_s10_O1S_cascade,' // &
      'prod_O1D,loss_O1D_per_s,dens_O1D,prod_O1S,loss_O1S_per_s,dens_O1S,' // &
      'ver5577_s1_eimpact_O,ver5577_s2_dissrec_O2p,ver5577_s3_N2A_O,ver5577_s4_O2p_N,' // &
      'ver5577_s5_N2D_NO,ver5577_s6_photodissoc_O2,' // &
      'ver4278_s1_eimpact_N2,ver4278_s2_photoion_N2,ver4278_s3_resonant_scatter,' // &
      'ne_cm3,ne_apriori_iri_cm3,ion_rate_total_cm3s,ion_rate_eimpact_cm3s,ion_rate_photo_bkg_cm3s,' // &
      'eion_O_cm3s,eion_O2_cm3s,eion_N2_cm3s,' // &
      'O_cm3,N2_cm3,O2_cm3,NO_cm3,N4S_cm3,Tn_K,Ti_K,Te_K,' // &
      'Op4S_cm3,O2p_cm3,NOp_cm3,N2p_cm3,Np_cm3,N2D_cm3'

    do j = 1, jmax
      write(6,'(f6.1,200(:",",es12.5))') z(j), &
        zeta(2,j), zeta(4,j), zeta(5,j), &
        r3914*(zceta(1,2,j)+zceta(2,2,j)), &
        zeta(1,j), zeta(3,j), zeta(5,j)*0.00185/0.00585, zeta(6,j), zeta(7,j), zeta(8,j), &
        zeta(9,j), zeta(10,j), zeta(11,j), zeta(12,j), zeta(13,j), zeta(14,j), zeta(15,j), &
        (zceta(ic,5,j), ic=1,10), &
        (zceta(ic,5,j)*loss(12,j)/0.00585, ic=1,10), &
        production(12,j), loss(12,j), zxden(12,j), production(11,j), loss(11,j), zxden(11,j), &
        (zceta(ic,4,j), ic=1,6), &
        (zceta(ic,2,j), ic=1,3), &
        ecalc(j), ze(j), tir(j), tei(j), tpi(j), &
        (sion(ii,j), ii=1,nmaj), &
        zo(j), zn2(j), zo2(j), zno(j), zns(j), ztn(j), zti(j), zte(j), &
        zxden(3,j), zxden(6,j), zxden(7,j), zxden(5,j), zxden(4,j), zxden(10,j)
    enddo
    write(6,'(a)') '# end'

  enddo

end program glowref
