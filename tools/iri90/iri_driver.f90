program iri_driver
! Stand-alone IRI-90 driver that calls IRI90 exactly as GLOW v0.981 mzgrid.f90 does
! (glowpython-4.0.4 src/GLOW/mzgrid.f90, iri90.f):
!   jf(1:12)=.true. except jf(5)=.false. (URSI foF2 coefficients), jmag=0 (geographic),
!   rz12 = -f107a  (negative => IRI treats it as the 12-month mean F10.7 "COV" and
!                   converts internally: Rz = 33.52*(sqrt(COV+85.12)-12.2)),
!   mmdd = -day_of_year, dhour = local solar time stl = ut/3600 + glong/15 (wrapped 0-24),
!   oarr(:)=0 on input, outf initialised to 0.
! Reads one line from stdin:  idate(yyyyddd or yyddd) ut_s glat glong f107a f107 ap grid
!   grid = 1 : 100..640 km every 2 km ;  grid = 2 : GLOW v0.981 102-level 80..640 km grid ;
!   grid = 3 : 80..500 km every 1 km (the crate's table, crates/aurora/data/ionosphere_iri90.csv)
! Writes CSV to stdout: altitude_km,ne_cm3,o_plus_fraction,te_k,ti_k
! (raw IRI output; nan where IRI gives no value, i.e. Te/Ti below 120 km; GLOW itself
!  then clamps ne>=100 cm-3 and Te,Ti >= MSIS Tn, which is NOT done here).
  implicit none
  integer :: idate, igrid, nz, j, iday, mmdd, jmag
  real :: ut, glat, glong, f107a, f107, ap, stl, rz12, rzeff
  real, allocatable :: z(:), outf(:,:)
  real :: oarr(30)
  logical :: jf(12)
  character(len=1024) :: iri90_dir
  character(len=8) :: dstr
  character(len=10) :: tstr
  real :: nan
  real, parameter :: zglow(102) = (/ &
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

  nan = transfer(int(z'7FC00000'), 1.0)
  if (command_argument_count() >= 1) then
    call get_command_argument(1, iri90_dir)
  else
    iri90_dir = '/work/glow-ref/src/glowpython-4.0.4/src/GLOW/data/iri90/'
  endif
  read(5,*) idate, ut, glat, glong, f107a, f107, ap, igrid

  if (igrid == 2) then
    nz = 102
    allocate(z(nz)); z = zglow
  else if (igrid == 3) then
    nz = 421
    allocate(z(nz))
    do j = 1, nz
      z(j) = 80. + 1.*(j-1)
    enddo
  else
    nz = 271
    allocate(z(nz))
    do j = 1, nz
      z(j) = 100. + 2.*(j-1)
    enddo
  endif
  allocate(outf(11,nz))

! local solar time exactly as GLOW drivers (glowbasic / glowref) compute it
  stl = ut/3600. + glong/15.
  if (stl < 0.) stl = stl + 24.
  if (stl >= 24.) stl = stl - 24.

! --- as mzgrid.f90 ---
  jf(:) = .true.
  jf(5) = .false.
  jmag = 0
  rz12 = -f107a
  iday = idate - idate/1000*1000
  mmdd = -iday
  outf = 0.
  oarr = 0.
  call iri90(jf,jmag,glat,glong,rz12,mmdd,stl,z,nz,iri90_dir,outf,oarr)
! ---------------------

  rzeff = 33.52*(sqrt(f107a+85.12)-12.2)   ! IRI-90 internal conversion
  call date_and_time(dstr, tstr)
  write(6,'(a)') '# IRI-90 (Bilitza 1990; GLOW-adapted iri90.f from glowpython-4.0.4 src/GLOW), ' // &
       'called exactly as GLOW v0.981 mzgrid.f90: jf(:)=T, jf(5)=F (URSI foF2), jmag=0, rz12=-F10.7a, mmdd=-doy'
  write(6,'(a,i8,a,i4,a,f8.1,a,f7.3,a,f7.2,a,f8.2,a,f7.1,a,f7.1,a,f6.1)') '# inputs: idate=',idate, &
       ' doy=',iday,' ut_s=',ut,' stl_h=',stl,' glat=',glat,' glong=',glong, &
       ' f107a=',f107a,' f107=',f107,' ap=',ap
  write(6,'(a,f7.1,a)') '# IRI uses only F10.7a (as 12-month mean COV) -> internal Rz12=',rzeff, &
       '; daily F10.7 and Ap are NOT used by IRI-90; no year input (monthly climatology)'
  write(6,'(a,es11.4,a,f7.2,a,f8.3,a,f8.3,a,f8.3)') '# NmF2_cm3=',oarr(1)/1.e6,' hmF2_km=',oarr(2), &
       ' sza_deg=',oarr(23),' dip_deg=',oarr(25),' modip_deg=',oarr(27)
  write(6,'(a)') '# o_plus_fraction = IRI O+ percentage/100; te_k, ti_k raw IRI (nan below 120 km, IRI limit)'
  write(6,'(a)') '# generated '//dstr(1:4)//'-'//dstr(5:6)//'-'//dstr(7:8)//'T'//tstr(1:2)//':'// &
       tstr(3:4)//':'//tstr(5:6)//' by /tmp/iri/iri_driver.f90'
  write(6,'(a)') 'altitude_km,ne_cm3,o_plus_fraction,te_k,ti_k'
  do j = 1, nz
    write(6,'(f6.1,4(",",es12.5))') z(j), v(outf(1,j),1.e-6), v(outf(5,j),1.e-2), &
         v(outf(4,j),1.), v(outf(3,j),1.)
  enddo
contains
  real function v(x, s)
    real, intent(in) :: x, s
    if (x < 0.) then
      v = nan
    else
      v = x*s
    endif
  end function v
end program iri_driver
