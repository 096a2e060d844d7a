% pc_reference.m - REKLAB's PC_stiffnessID on the five stationary ankle trials, for JointBench's parity table.
%
% Run by tools/reklab/reference.py (which converts the trials to plain arrays and passes the paths):
%   octave --no-gui --eval "toolbox='...'; trials='trials.mat'; out='prefix'; run('tools/reklab/pc_reference.m')"
%
% toolbox: a checkout of reklab/reklab_public (GPL-2; not part of this repository); trials: a .mat file of plain
% arrays z_pf, z_pf2, z_df, z_df2, z_df3 (60000 x 2: angle rad, torque N.m; 1 kHz); out: the output prefix.
% GNU Octave cannot read the toolbox's own experimental_data.mat (its variables are MATLAB nldat objects, stored
% as MCOS class data, which Octave's load returns as opaque structs), so each trial is rebuilt here as an nldat
% from the same arrays (../shared/data/reklab-ankle/ankle_stationary.npz) with domainIncr 0.001 s.
%
% The settings are PC_stiffnessID's defaults with the rectifier reflex of pcDemo.m ('reflex_id_method','rect'):
% decimation by 10, a +-40 ms two-sided intrinsic IRF, a one-sided reflex IRF of 1000 ms (100 lags at 100 Hz:
% 0 ... 0.99 s) of the half-wave rectified velocity, the toolbox's pseudo-inverse IRFs, tolerance 0.05 % VAF,
% at most 10 iterations. The velocity is ddt (five-point parabola) of the angle at 1 kHz, then decimated.
%
% Writes <out>_summary.csv (one row per trial: intrinsic K = the intrinsic IRF's sum times its sampling
% increment, reflex gain = the same of the reflex IRF, N.m per rad/s of rectified velocity, VAFT, VAFi, VAFr,
% CPU seconds) and <out>_irfs.csv (trial, pathway, lag_s, h: the IRFs as the toolbox stores them, per second).
% Needs Octave's signal package (decimate): Octave's decimate keeps samples 1, 11, 21, ... (MATLAB's keeps
% 10, 20, ...); both signals of a trial are decimated alike, so the fit is unchanged up to that half-period shift.
pkg load signal
addpath(genpath(fullfile(toolbox, 'nlid_tools')));
addpath(genpath(fullfile(toolbox, 'utility_tools')));
addpath(fullfile(toolbox, 'stiffnessID'));
warning('off', 'all');
names = {'z_pf', 'z_pf2', 'z_df', 'z_df2', 'z_df3'};
s = load(trials);
fs = fopen([out '_summary.csv'], 'w');
fprintf(fs, 'trial,intrinsic_K,reflex_gain,vaf_total,vaf_intrinsic,vaf_reflex,cpu_s\n');
fi = fopen([out '_irfs.csv'], 'w');
fprintf(fi, 'trial,pathway,lag_s,h\n');
for k = 1:numel(names)
  z = nldat(s.(names{k}), 'domainIncr', 0.001, 'chanNames', {'angle', 'torque'});
  t0 = cputime;
  [hI, mR, nlmS, VAFT, VAFi, VAFr] = PC_stiffnessID(z, 'reflex_id_method', 'rect');
  cpu = cputime - t0;
  hi = double(hI); hr = double(mR);
  ti = get(hI, 'domainIncr'); tr = get(mR, 'domainIncr');
  fprintf(fs, '%s,%.10g,%.10g,%.10g,%.10g,%.10g,%.3f\n', names{k}, sum(hi) * ti, sum(hr) * tr, VAFT, VAFi, VAFr, cpu);
  li = get(hI, 'domainStart') + (0:numel(hi) - 1) * ti;
  lr = get(mR, 'domainStart') + (0:numel(hr) - 1) * tr;
  for j = 1:numel(hi), fprintf(fi, '%s,intrinsic,%.6g,%.10g\n', names{k}, li(j), hi(j)); end
  for j = 1:numel(hr), fprintf(fi, '%s,reflex,%.6g,%.10g\n', names{k}, lr(j), hr(j)); end
end
fclose(fs); fclose(fi);
