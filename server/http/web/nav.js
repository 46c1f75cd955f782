// The pages and who sees each in the menu.
export const PAGES = [
  { page: 'live', title: 'Live stations', roles: ['instructor', 'admin'] },
  { page: 'records', title: 'Sessions', roles: ['instructor', 'evaluator', 'admin'] },
  { page: 'evaluate', title: 'Evaluate', roles: ['evaluator', 'admin'] },
  { page: 'training', title: 'Training', roles: ['instructor', 'admin'] },
  { page: 'reports', title: 'Reports', roles: ['instructor', 'evaluator', 'admin'] },
  { page: 'admin', title: 'Administration', roles: ['admin'] },
  { page: 'mine', title: 'My training', roles: ['trainee', 'admin'] },
];
