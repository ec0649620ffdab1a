#include <stdio.h>
#include <stdlib.h>
#include <sys/mman.h>
#include <time.h>
static double now(){struct timespec t;clock_gettime(CLOCK_MONOTONIC,&t);return t.tv_sec+t.tv_nsec*1e-9;}
int main(int argc,char**argv){
  size_t n=(size_t)atoi(argv[1])<<20; int huge=atoi(argv[2]);
  double t=now();
  char*p=mmap(0,n,PROT_READ|PROT_WRITE,MAP_PRIVATE|MAP_ANONYMOUS,-1,0);
  if(huge) madvise(p,n,MADV_HUGEPAGE);
  for(size_t i=0;i<n;i+=4096)p[i]=1; double t1=now();
  printf("huge %d: %.3f s (%.2f GB/s)\n",huge,t1-t,n/1e9/(t1-t));
}
