// The nine evaluation indexes of the coil-spring paper §4.4 as a physician reads them: a plain name, the
// question, and what a 1, a 5 and a 10 mean. The API's names (index_names) stay the stored keys.
export const INDEXES = [
  { key: 'effectiveness', name: 'Training value',
    question: 'Would practising this task here make a trainee better at it?',
    anchors: ['no training value', 'useful for the basics only', 'as good as supervised practice'] },
  { key: 'force_feedback', name: 'Force feedback',
    question: 'Does the tissue push back as real tissue would, in size and in timing?',
    anchors: ['wrong or missing', 'plausible but off in size or timing', 'indistinguishable from tissue'] },
  { key: 'real_time', name: 'Responsiveness',
    question: 'Do the picture and the force follow the hand without a felt delay?',
    anchors: ['a lag that disturbs the task', 'a noticeable lag', 'no delay noticed'] },
  { key: 'stability', name: 'Stability',
    question: 'Did the simulation stay steady (no buzzing, jumps, or stuck tissue)?',
    anchors: ['unusable: vibrates or breaks', 'occasional glitches', 'steady throughout'] },
  { key: 'deformation_efficiency', name: 'Deformation',
    question: 'Does the tissue deform where and as much as it should?',
    anchors: ['wrong shape or place', 'roughly right', 'convincing everywhere'] },
  { key: 'fidelity', name: 'Anatomical fidelity',
    question: 'Do the shape, size and behaviour match the anatomy?',
    anchors: ['unrecognisable', 'recognisable, simplified', 'true to the anatomy'] },
  { key: 'visual_fluency', name: 'Visual smoothness',
    question: 'Is the motion on screen smooth?',
    anchors: ['jerky', 'mostly smooth', 'perfectly smooth'] },
  { key: 'immersion', name: 'Immersion',
    question: 'Did the trainee (or you) forget it was a simulator?',
    anchors: ['never', 'at moments', 'throughout'] },
  { key: 'texture', name: 'Look of the tissue',
    question: 'Do the surface and its colour read as real tissue?',
    anchors: ['artificial', 'acceptable', 'realistic'] },
];
export const ANCHOR_SCORES = [1, 5, 10];
// The plain name of a stored index key; without the key (a trainee does not read the weight
// sets), of index j in the stored order, which INDEXES keeps.
export function indexName(key, j) {
  const x = INDEXES.find((i) => i.key === key) || (key === undefined && INDEXES[j]);
  return x ? x.name : key;
}
// Training moments (minutes into a trainee's training) an evaluation may be made at.
export const MOMENTS = [0, 30, 60];
export function momentText(m) {
  return m === null || m === undefined ? 'not at a training moment' : `${m} min into training`;
}
